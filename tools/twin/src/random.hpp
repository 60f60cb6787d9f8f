// Reproducible random draws for the twin (internal).
#pragma once

#include <cstdint>
#include <random>

#include "stepcal/common/types.hpp"

namespace stepcal::twin {

/// Independent random streams of one seed: changing what one stream is used for leaves the
/// others unchanged.
enum class Stream : uint32_t {
  kTruth = 1,
  kPoses = 2,
  kNoise = 3,
  kRandomPoseList = 4,
  kModelTwinNoise = 5,  ///< the twin of a calibrated robot (model_twin.hpp)
  kStation = 6,         ///< where tracker station k >= 1 stands (TwinOptions::station)
  kLoadOrder = 7,       ///< the fit rows' order when TwinOptions::load_order is "mixed"
};

/// std::mt19937_64 with platform-independent uniform and normal variates.
class Rng {
 public:
  /// The stream of one seed at tracker station `station` (TwinOptions::station): station 0 is
  /// the seed's own; each station k >= 1 has one of its own, independent of every other's.
  Rng(uint64_t seed, Stream stream, uint32_t station = 0);
  /// Uniform in [lo, hi).
  double uniform(double lo, double hi);
  /// Standard normal (Box–Muller).
  double normal();
  /// Three independent N(0, sigma²) values.
  Vec3 normal3(double sigma);
  /// Uniformly distributed unit vector.
  Vec3 unitVector();

 private:
  // Uniform in [0, 1) with 53 random bits.
  double canonical();
  std::mt19937_64 engine_;
};

}  // namespace stepcal::twin
