#include "random.hpp"

#include <cmath>
#include <vector>

#include "stepcal/common/units.hpp"

namespace stepcal::twin {

Rng::Rng(uint64_t seed, Stream stream, uint32_t station) {
  std::vector<uint32_t> words = {static_cast<uint32_t>(seed & 0xffffffffu),
                                 static_cast<uint32_t>(seed >> 32), static_cast<uint32_t>(stream)};
  // Station 0 keeps its three words; a fourth makes station k's sequences none of station 0's.
  if (station > 0) words.push_back(station);
  std::seed_seq seq(words.begin(), words.end());
  engine_.seed(seq);
}

double Rng::canonical() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; }

double Rng::uniform(double lo, double hi) { return lo + (hi - lo) * canonical(); }

double Rng::normal() {
  // 1 − u lies in (0, 1], so the logarithm is finite.
  const double u1 = 1.0 - canonical();
  const double u2 = canonical();
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * kPi * u2);
}

Vec3 Rng::normal3(double sigma) {
  const double x = normal();
  const double y = normal();
  const double z = normal();
  return sigma * Vec3(x, y, z);
}

Vec3 Rng::unitVector() {
  // A normalised isotropic Gaussian is uniform on the sphere; redraw the (never seen) zero.
  for (;;) {
    const Vec3 v = normal3(1.0);
    const double n = v.norm();
    if (n > 1e-12) return v / n;
  }
}

}  // namespace stepcal::twin
