// libFuzzer target for parseModel: no input may crash it, read out of bounds, trip a sanitizer or
// throw anything but InputError. Not part of the CMake build (that uses g++); build and run with
// `tests/system/fuzz.sh model_file SECONDS`, or by hand from the repository root:
//
//   clang++ -std=c++17 -O2 -g -Icommon/include $(pkg-config --cflags eigen3) \
//     -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined \
//     tests/fuzz/fuzz_model_file.cpp \
//     common/src/{error,lie,chain,compliance,mechanisms,model_file,atomic_file}.cpp \
//     -o fuzz_model_file
//
// Each input is parsed twice: as given (the checksum refuses nearly every mutation), then with
// its size field and CRC re-stamped, so the fuzzer reaches the structural and semantic checks.
// A file that parses must serialise back to exactly the same bytes.
//
// Built with -DSTEPCAL_FUZZ_SEED_MAIN (and without -fsanitize=fuzzer) the same file is instead
// a seed generator: `make_seeds FOLDER` writes small valid models to start the corpus from (one
// with every section filled, a mechanism of every kind included).
#include <cstdint>
#include <cstdlib>
#include <vector>

#include "stepcal/common/error.hpp"
#include "stepcal/common/model_file.hpp"

#ifndef STEPCAL_FUZZ_SEED_MAIN

namespace {

constexpr size_t kHeaderBytes = 24;
constexpr size_t kCrcBytes = 4;

void parseOrRefuse(const uint8_t* data, size_t size) {
  stepcal::CalibratedModel model;
  try {
    model = stepcal::parseModel(data, size, "fuzz input");
  } catch (const stepcal::InputError&) {
    return;
  }
  // Every accepted file is canonical: the writer must reproduce it bit for bit.
  if (stepcal::serializeModel(model) != std::vector<uint8_t>(data, data + size)) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  parseOrRefuse(data, size);
  if (size < kHeaderBytes + kCrcBytes) return 0;
  std::vector<uint8_t> stamped(data, data + size);
  for (size_t i = 0; i < 8; ++i) stamped[16 + i] = uint8_t(uint64_t(size) >> (8 * i));
  const uint32_t crc = stepcal::crc32Ieee(stamped.data(), size - kCrcBytes);
  for (size_t i = 0; i < kCrcBytes; ++i) stamped[size - kCrcBytes + i] = uint8_t(crc >> (8 * i));
  parseOrRefuse(stamped.data(), stamped.size());
  return 0;
}

#else

#include <cstdio>
#include <string>

#include "../support/random_gpr.hpp"
#include "seed_file.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/units.hpp"

namespace {

/// A six-joint arm shaped like the IRB 4400 (metres), with a flange and a sensor frame.
stepcal::KinematicChain seedChain() {
  using stepcal::Pose;
  using stepcal::Vec3;
  std::vector<stepcal::ChainJoint> joints(6);
  std::vector<Pose> initial(7, Pose::Identity());
  const Vec3 offsets[7] = {{0, 0, 0.68},   {0.2, 0, 0}, {0, 0, 0.89}, {0, 0, 0.15},
                           {0.88, 0, 0},   {0, 0, 0},   {0.14, 0, 0}};
  for (int i = 0; i < 6; ++i) {
    joints[size_t(i)].name = "joint_" + std::to_string(i + 1);
    joints[size_t(i)].twist_Local << 0, 0, 0, 0, 0, 1;
    initial[size_t(i)].linear() = stepcal::lie::rotationFromRpy(i % 2 ? stepcal::kPi / 2 : 0, 0, 0.1 * i);
  }
  for (int k = 0; k < 7; ++k) initial[size_t(k)].translation() = offsets[k];
  Pose X_SixSensor = Pose::Identity();
  X_SixSensor.translation() = Vec3(0, 0, 0.045);
  return stepcal::KinematicChain(joints, initial,
                                 {{"flange", 6, Pose::Identity()}, {"ft_sensor", 6, X_SixSensor}});
}

void writeSeed(const std::string& path, const stepcal::CalibratedModel& model) {
  stepcal::fuzz::writeSeedBytes(path, stepcal::serializeModel(model));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s SEED_FOLDER\n", argv[0]);
    return 2;
  }
  const std::string folder = argv[1];
  stepcal::CalibratedModel bare;
  bare.chain_Tracker = seedChain();
  bare.nominal_Base = seedChain();
  writeSeed(folder + "/bare.model", bare);

  stepcal::CalibratedModel full = bare;
  full.X_TrackerBase.linear() = stepcal::lie::rotationFromRpy(0.01, -0.02, 2.3);
  full.X_TrackerBase.translation() = stepcal::Vec3(3.8, -1.3, 0.4);
  full.chain_Tracker = bare.chain_Tracker.rerooted(full.X_TrackerBase);
  full.sensor_frame = 1;
  full.gravity_Base = stepcal::Vec3(0, 0, -9.80665);
  full.compliance_rad_per_nm = stepcal::JointVector::Constant(6, 2e-6);
  full.compliance_sigma_rad_per_nm = stepcal::JointVector::Constant(6, 1e-7);
  full.gpr = stepcal::test::randomConsistentGpr(8, 12, 6);
  using stepcal::MechanismKind;
  std::vector<double> self_weight;
  for (int k = 0; k < 6; ++k) {
    self_weight.insert(self_weight.end(), {40.0 - 5 * k, 4.0, 0.5, -1.0});
  }
  full.mechanisms = {
      {MechanismKind::kBacklash, 1, -1, 0, {2e-4, 5.0}, {1e-5, 0.0}},
      {MechanismKind::kSelfWeight, -1, -1, 0, self_weight, std::vector<double>(24, 0.1)},
      {MechanismKind::kTransmissionError, 2, -1, 2, {0.0, 1e-5, 3e-5, -1e-5}, {1e-6, 1e-6, 1e-6, 1e-6},
       {{0.5, 4.0}, 0.1}},
      {MechanismKind::kNonlinearStiffness, 3, -1, 0, {1e-6, 50.0, 400.0}, {1e-7, 5.0, 0.0}},
      {MechanismKind::kThermalExpansion, -1, -1, 0, {1.2e-5, 20.0}, {1e-6, 0.0}},
      {MechanismKind::kSensorBias, -1, -1, 0, {0.5, -0.3, 1.2, 0.01, 0.02, -0.03},
       std::vector<double>(6, 0.01)},
      {MechanismKind::kJointCoupling, 4, 3, 0, {1e-4}, {1e-5}}};
  full.provenance = {"0123abcd", "2024-05-01T12:34:56Z", "stepcal 0.1.0", "/data/c1",
                     {{"POE + stiffness + GPR", 20, 30, 1e-4, 3e-4, 2e-4}}};
  writeSeed(folder + "/full.model", full);
  return 0;
}

#endif
