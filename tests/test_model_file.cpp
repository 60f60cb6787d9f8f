// Model file: bit-exact round trips (a mechanism of every kind included), every corrupted byte
// and every truncation refused, each semantic check proven by editing the bytes and re-fixing the
// checksum, atomic writes.
#include <gtest/gtest.h>

#include <sys/resource.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <functional>
#include <iostream>
#include <limits>
#include <random>

#include <Eigen/Cholesky>

#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/model_file.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/common/urdf.hpp"
#include "support/mechanisms.hpp"

namespace stepcal {
namespace {

namespace fs = std::filesystem;

const std::string kIrb = std::string(STEPCAL_ROBOTS_DIR) + "/irb4400.urdf";
constexpr size_t kHeaderBytes = 24;

/// Squared-exponential ARD kernel (docs/method.md eq. 27), written independently of the loader's.
Eigen::MatrixXd kernel(const Eigen::MatrixXd& X, const Eigen::VectorXd& length_scales,
                       double signal_sigma) {
  const Eigen::Index m = X.rows();
  Eigen::MatrixXd K(m, m);
  for (Eigen::Index i = 0; i < m; ++i) {
    for (Eigen::Index j = 0; j < m; ++j) {
      const double d2 =
          ((X.row(i) - X.row(j)).transpose().array() / length_scales.array()).square().sum();
      K(i, j) = signal_sigma * signal_sigma * std::exp(-0.5 * d2);
    }
  }
  return K;
}

/// Random GPR parts (inputs q, F → outputs ξ) with α solved by Cholesky, as the trainer does.
GprParameters randomGpr(std::mt19937_64& rng, int m, int D, int P, double length_scale = 2.0,
                        double signal_sigma = 0.9, double noise_sigma = 0.08) {
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  const auto randn = [&](Eigen::Index rows, Eigen::Index cols) {
    Eigen::MatrixXd M(rows, cols);
    for (Eigen::Index i = 0; i < M.size(); ++i) M(i) = normal(rng);
    return M;
  };
  GprParameters g;
  g.inputs_normalised = randn(m, D);
  g.input_offset = 0.3 * randn(D, 1);
  g.input_scale = Eigen::VectorXd(D);
  g.length_scales = Eigen::VectorXd(D);
  for (int d = 0; d < D; ++d) {
    g.input_scale(d) = d < D / 2 ? 1.2 + uniform(rng) : 50.0 + 100.0 * uniform(rng);
    g.length_scales(d) = length_scale * (1.0 + uniform(rng));
  }
  g.output_mean = 1e-4 * randn(P, 1);
  g.output_scale = Eigen::VectorXd::Constant(P, 2e-4) + 1e-4 * randn(P, 1).cwiseAbs();
  g.signal_sigma = signal_sigma;
  g.noise_sigma = noise_sigma;
  g.targets_standardised = randn(m, P);
  const Eigen::MatrixXd K = kernel(g.inputs_normalised, g.length_scales, g.signal_sigma) +
                            g.noise_sigma * g.noise_sigma * Eigen::MatrixXd::Identity(m, m);
  g.alpha = K.llt().solve(g.targets_standardised);
  return g;
}

/// An IRB 4400 model as the trainer and the diagnosis would write it: calibrated, registered,
/// all three steps, a mechanism of every kind.
CalibratedModel realisticModel(int m = 300) {
  std::mt19937_64 rng(42);
  std::normal_distribution<double> normal(0.0, 1.0);
  const KinematicChain chain_Base =
      chainFromUrdfFile(kIrb, "base_link", "tmac", {"flange", "ft_sensor"});
  Eigen::VectorXd delta(6 * (chain_Base.dof() + 1));
  for (Eigen::Index i = 0; i < delta.size(); ++i) delta(i) = 1e-3 * normal(rng);

  CalibratedModel model;
  model.X_TrackerBase = Pose::Identity();
  model.X_TrackerBase.linear() = lie::rotationFromRpy(0.01, -0.02, 2.3);
  model.X_TrackerBase.translation() = Vec3(3.812, -1.274, 0.391);
  model.chain_Tracker = chain_Base.corrected(delta).rerooted(model.X_TrackerBase);
  model.nominal_Base = chain_Base;
  model.sensor_frame = model.chain_Tracker.findFrame("ft_sensor");
  model.gravity_Base = Vec3(0.0, 0.0, -9.80665);
  // Paper's identified joint stiffnesses (N·m/rad), as compliances.
  const Eigen::Matrix<double, 6, 1> stiffness(501130, 633590, 508209, 124391, 75782, 74226);
  model.compliance_rad_per_nm = stiffness.cwiseInverse();
  model.compliance_sigma_rad_per_nm = 0.05 * model.compliance_rad_per_nm;
  model.mechanisms = test::mechanismOfEveryKind();
  model.gpr = randomGpr(rng, m, 12, 6);
  ModelProvenance& p = model.provenance;
  p.campaign_hash = "9f86d081884c7d659a2feaa0c55ad015a3bf4f1b2b0b822cd15d6c15b0f00a08";
  p.created_utc = "2024-05-01T12:34:56Z";
  p.trainer_version = "stepcal 0.1.0";
  p.campaign_path = "/data/campaigns/irb4400-2024-05";
  p.validation = {{"POE", 20, 30, 0.5712 * kMPerMm, 1.41 * kMPerMm, 0.0286 * kRadPerDeg},
                  {"POE + stiffness", 20, 30, 0.3952 * kMPerMm, 0.97 * kMPerMm, 0.0176 * kRadPerDeg},
                  {"POE + stiffness + GPR", 20, 30, 0.1032 * kMPerMm, 0.31 * kMPerMm, 0.0104 * kRadPerDeg},
                  {"POE + stiffness + GPR", 40, 30, 0.1129 * kMPerMm, 0.35 * kMPerMm, 0.0122 * kRadPerDeg}};
  return model;
}

bool sameMatrix(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() && (a.array() == b.array()).all();
}

void expectSameChain(const KinematicChain& ca, const KinematicChain& cb) {
  ASSERT_EQ(ca.dof(), cb.dof());
  for (int i = 0; i < ca.dof(); ++i) {
    const ChainJoint& ja = ca.joints()[size_t(i)];
    const ChainJoint& jb = cb.joints()[size_t(i)];
    EXPECT_EQ(ja.name, jb.name);
    EXPECT_TRUE(sameMatrix(ja.twist_Local, jb.twist_Local));
    EXPECT_EQ(ja.lower_rad, jb.lower_rad);
    EXPECT_EQ(ja.upper_rad, jb.upper_rad);
  }
  for (int k = 0; k <= ca.dof(); ++k) {
    EXPECT_TRUE(sameMatrix(ca.initialPose(k).matrix(), cb.initialPose(k).matrix())) << k;
  }
  ASSERT_EQ(ca.frames().size(), cb.frames().size());
  for (size_t i = 0; i < ca.frames().size(); ++i) {
    EXPECT_EQ(ca.frames()[i].name, cb.frames()[i].name);
    EXPECT_EQ(ca.frames()[i].parent, cb.frames()[i].parent);
    EXPECT_TRUE(sameMatrix(ca.frames()[i].X_ParentFrame.matrix(),
                           cb.frames()[i].X_ParentFrame.matrix()));
  }
}

void expectSameModel(const CalibratedModel& a, const CalibratedModel& b) {
  expectSameChain(a.chain_Tracker, b.chain_Tracker);
  expectSameChain(a.nominal_Base, b.nominal_Base);
  EXPECT_TRUE(sameMatrix(a.X_TrackerBase.matrix(), b.X_TrackerBase.matrix()));
  EXPECT_EQ(a.sensor_frame, b.sensor_frame);
  EXPECT_TRUE(sameMatrix(a.gravity_Base, b.gravity_Base));
  EXPECT_TRUE(sameMatrix(a.compliance_rad_per_nm, b.compliance_rad_per_nm));
  EXPECT_TRUE(sameMatrix(a.compliance_sigma_rad_per_nm, b.compliance_sigma_rad_per_nm));
  ASSERT_EQ(a.mechanisms.size(), b.mechanisms.size());
  for (size_t i = 0; i < a.mechanisms.size(); ++i) {
    const Mechanism& ma = a.mechanisms[i];
    const Mechanism& mb = b.mechanisms[i];
    EXPECT_EQ(ma.kind, mb.kind) << i;
    EXPECT_EQ(ma.joint, mb.joint) << i;
    EXPECT_EQ(ma.source_joint, mb.source_joint) << i;
    EXPECT_EQ(ma.order, mb.order) << i;
    EXPECT_EQ(ma.parameters, mb.parameters) << i;
    EXPECT_EQ(ma.sigma, mb.sigma) << i;
    EXPECT_EQ(ma.coverage.arcs_rad, mb.coverage.arcs_rad) << i;
    EXPECT_EQ(ma.coverage.fade_rad, mb.coverage.fade_rad) << i;
  }
  ASSERT_EQ(a.gpr.has_value(), b.gpr.has_value());
  if (a.gpr) {
    const GprParameters& ga = *a.gpr;
    const GprParameters& gb = *b.gpr;
    EXPECT_TRUE(sameMatrix(ga.inputs_normalised, gb.inputs_normalised));
    EXPECT_TRUE(sameMatrix(ga.input_offset, gb.input_offset));
    EXPECT_TRUE(sameMatrix(ga.input_scale, gb.input_scale));
    EXPECT_TRUE(sameMatrix(ga.output_mean, gb.output_mean));
    EXPECT_TRUE(sameMatrix(ga.output_scale, gb.output_scale));
    EXPECT_TRUE(sameMatrix(ga.length_scales, gb.length_scales));
    EXPECT_EQ(ga.signal_sigma, gb.signal_sigma);
    EXPECT_EQ(ga.noise_sigma, gb.noise_sigma);
    EXPECT_TRUE(sameMatrix(ga.targets_standardised, gb.targets_standardised));
    EXPECT_TRUE(sameMatrix(ga.alpha, gb.alpha));
    EXPECT_EQ(ga.payload_force_reference_n, gb.payload_force_reference_n);
  }
  const ModelProvenance& pa = a.provenance;
  const ModelProvenance& pb = b.provenance;
  EXPECT_EQ(pa.campaign_hash, pb.campaign_hash);
  EXPECT_EQ(pa.created_utc, pb.created_utc);
  EXPECT_EQ(pa.trainer_version, pb.trainer_version);
  EXPECT_EQ(pa.campaign_path, pb.campaign_path);
  ASSERT_EQ(pa.validation.size(), pb.validation.size());
  for (size_t i = 0; i < pa.validation.size(); ++i) {
    EXPECT_EQ(pa.validation[i].method, pb.validation[i].method);
    EXPECT_EQ(pa.validation[i].load_kg, pb.validation[i].load_kg);
    EXPECT_EQ(pa.validation[i].rows, pb.validation[i].rows);
    EXPECT_EQ(pa.validation[i].mean_position_m, pb.validation[i].mean_position_m);
    EXPECT_EQ(pa.validation[i].max_position_m, pb.validation[i].max_position_m);
    EXPECT_EQ(pa.validation[i].mean_orientation_rad, pb.validation[i].mean_orientation_rad);
  }
}

CalibratedModel parse(const std::vector<uint8_t>& bytes) {
  return parseModel(bytes.data(), bytes.size(), "test.model");
}

/// Message of the InputError parsing `bytes` throws, or "" when it parses.
std::string refusal(const std::vector<uint8_t>& bytes) {
  try {
    parse(bytes);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// Little-endian edits at a byte offset, as the format stores them.
void putU32(std::vector<uint8_t>& b, size_t at, uint32_t v) {
  for (int i = 0; i < 4; ++i) b[at + size_t(i)] = uint8_t(v >> (8 * i));
}
void putF64(std::vector<uint8_t>& b, size_t at, double v) {
  uint64_t bits = 0;
  std::memcpy(&bits, &v, 8);
  for (int i = 0; i < 8; ++i) b[at + size_t(i)] = uint8_t(bits >> (8 * i));
}
double getF64(const std::vector<uint8_t>& b, size_t at) {
  uint64_t bits = 0;
  for (int i = 0; i < 8; ++i) bits |= uint64_t(b[at + size_t(i)]) << (8 * i);
  double v = 0;
  std::memcpy(&v, &bits, 8);
  return v;
}
uint32_t getU32(const std::vector<uint8_t>& b, size_t at) {
  uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v |= uint32_t(b[at + size_t(i)]) << (8 * i);
  return v;
}

/// Re-stamps the size field and the CRC, so only the deliberate edit is left to be caught.
void refix(std::vector<uint8_t>& b) {
  const uint64_t size = b.size();
  for (int i = 0; i < 8; ++i) b[16 + size_t(i)] = uint8_t(size >> (8 * i));
  putU32(b, b.size() - 4, crc32Ieee(b.data(), b.size() - 4));
}

/// Byte offset of a section's payload, found by walking the section headers.
size_t payloadOf(const std::vector<uint8_t>& b, const char (&tag)[5]) {
  size_t at = kHeaderBytes;
  while (at + 16 <= b.size() - 4) {
    uint64_t length = 0;
    for (int i = 0; i < 8; ++i) length |= uint64_t(b[at + 8 + size_t(i)]) << (8 * i);
    if (std::memcmp(&b[at], tag, 4) == 0) return at + 16;
    at += 16 + size_t(length);
  }
  ADD_FAILURE() << "no section " << tag;
  return 0;
}

/// Byte offset of mechanism record i in MECH (kind, joint, source_joint, order, p, then p
/// parameters, p sigmas, the coverage's arc count a, 2a arc numbers and its fade).
size_t mechanismAt(const std::vector<uint8_t>& b, size_t i) {
  size_t at = payloadOf(b, "MECH") + 4;
  for (size_t j = 0; j < i; ++j) {
    at += 20 + 16 * size_t(getU32(b, at + 16));
    at += 4 + 16 * size_t(getU32(b, at)) + 8;
  }
  return at;
}

/// Byte offset of the GPR's first normalised input, for D inputs and P outputs.
size_t gprInputsAt(const std::vector<uint8_t>& b, size_t D, size_t P) {
  return payloadOf(b, "GPR ") + 12 + 8 * (3 * D + 2 * P + 2);
}

class ModelFileTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    model_ = new CalibratedModel(realisticModel());
    bytes_ = new std::vector<uint8_t>(serializeModel(*model_));
  }
  static void TearDownTestSuite() {
    delete model_;
    delete bytes_;
  }
  static const CalibratedModel& model() { return *model_; }
  static const std::vector<uint8_t>& bytes() { return *bytes_; }

 private:
  static CalibratedModel* model_;
  static std::vector<uint8_t>* bytes_;
};
CalibratedModel* ModelFileTest::model_ = nullptr;
std::vector<uint8_t>* ModelFileTest::bytes_ = nullptr;

/// A fresh empty folder, removed at the end of the test.
class ScratchFolder {
 public:
  ScratchFolder() {
    path_ = fs::temp_directory_path() /
            ("stepcal_model_file_" + std::to_string(::getpid()) + "_" +
             ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~ScratchFolder() { fs::remove_all(path_); }
  const fs::path& path() const { return path_; }
  std::vector<std::string> entries() const {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(path_)) names.push_back(e.path().filename());
    return names;
  }

 private:
  fs::path path_;
};

/// Bit-at-a-time CRC-32, the definition the table-driven one must match.
uint32_t crc32Bitwise(const uint8_t* data, size_t size) {
  uint32_t c = 0xFFFFFFFFu;
  for (size_t i = 0; i < size; ++i) {
    c ^= data[i];
    for (int k = 0; k < 8; ++k) c = (c & 1u) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
  }
  return ~c;
}

TEST(Crc32, StandardCheckValueAndEveryLengthAndAlignment) {
  const std::string text = "123456789";
  EXPECT_EQ(crc32Ieee(reinterpret_cast<const uint8_t*>(text.data()), text.size()), 0xCBF43926u);
  EXPECT_EQ(crc32Ieee(nullptr, 0), 0u);
  std::mt19937 rng(7);
  std::vector<uint8_t> bytes(100);
  for (uint8_t& b : bytes) b = uint8_t(rng());
  for (size_t start = 0; start < 8; ++start) {
    for (size_t length = 0; start + length <= bytes.size(); ++length) {
      ASSERT_EQ(crc32Ieee(bytes.data() + start, length), crc32Bitwise(bytes.data() + start, length))
          << start << " " << length;
    }
  }
}

TEST_F(ModelFileTest, RoundTripIsBitExactAndKeepsEveryField) {
  const CalibratedModel parsed = parse(bytes());
  expectSameModel(model(), parsed);
  EXPECT_EQ(serializeModel(parsed), bytes());
  // m = 300, D = 12, P = 6: inputs, targets and α dominate; no Cholesky factor is stored.
  std::cout << "[          ] model file size for m = 300, D = 12, P = 6: " << bytes().size()
            << " bytes\n";
  RecordProperty("model_file_bytes_m300", std::to_string(bytes().size()));
  EXPECT_LT(bytes().size(), 100000u);
  EXPECT_GT(bytes().size(), 300u * (12 + 6 + 6) * 8);
}

TEST_F(ModelFileTest, RoundTripWithoutOptionalSteps) {
  CalibratedModel bare = model();
  bare.gpr.reset();
  bare.compliance_rad_per_nm.resize(0);
  bare.compliance_sigma_rad_per_nm.resize(0);
  bare.sensor_frame = -1;
  bare.provenance = {};
  bare.mechanisms.clear();
  // A continuous joint has infinite limits.
  ChainJoint continuous = bare.chain_Tracker.joints()[5];
  continuous.lower_rad = -std::numeric_limits<double>::infinity();
  continuous.upper_rad = std::numeric_limits<double>::infinity();
  std::vector<ChainJoint> joints = bare.chain_Tracker.joints();
  joints[5] = continuous;
  bare.chain_Tracker = KinematicChain(joints, bare.chain_Tracker.initialPoses(),
                                      bare.chain_Tracker.frames());
  const std::vector<uint8_t> b = serializeModel(bare);
  const CalibratedModel parsed = parse(b);
  expectSameModel(bare, parsed);
  EXPECT_EQ(serializeModel(parsed), b);
  EXPECT_LT(b.size(), 3500u);
}

// A GPR per payload force writes its reference force after α (8 bytes); the paper's GPR is
// written as before (its bytes are those of every earlier file); the loader refuses a reference
// that is not a force > 0.
TEST_F(ModelFileTest, GprPerPayloadForceRoundTripsAndItsReferenceIsChecked) {
  CalibratedModel per_force = model();
  per_force.gpr->payload_force_reference_n = 294.2;
  const std::vector<uint8_t> b = serializeModel(per_force);
  EXPECT_EQ(b.size(), bytes().size() + 8);
  const CalibratedModel parsed = parse(b);
  expectSameModel(per_force, parsed);
  EXPECT_EQ(serializeModel(parsed), b);
  EXPECT_EQ(parse(bytes()).gpr->payload_force_reference_n, 0.0);

  const size_t reference_at = payloadOf(b, "PROV") - 16 - 8;
  ASSERT_EQ(getF64(b, reference_at), 294.2);
  for (const double bad : {0.0, -3.0, std::nan("")}) {
    std::vector<uint8_t> edited = b;
    putF64(edited, reference_at, bad);
    refix(edited);
    EXPECT_NE(refusal(edited).find("gpr.payload_force_reference_n"), std::string::npos) << bad;
  }
  per_force.gpr->payload_force_reference_n = -1.0;
  EXPECT_THROW(serializeModel(per_force), InputError);
}

// ACCU, the accuracy factors, follows PROV when the model has them: a model without them is
// written as before (the bytes of every earlier file), one with them round trips bit for bit,
// and each bad value is refused naming its field.
TEST_F(ModelFileTest, AccuracyFactorsRoundTripAreOptionalAndCheckedByField) {
  CalibratedModel with = model();
  const int n = with.chain_Tracker.dof();
  std::mt19937_64 rng(45);
  std::normal_distribution<double> normal(0.0, 1e-5);
  AccuracyFactors a;
  a.position_noise_m = 15e-6;
  a.orientation_noise_rad = 1.7e-4;
  a.geometry_factor.resize(6 * (n + 1), 30);
  for (Eigen::Index i = 0; i < a.geometry_factor.size(); ++i) a.geometry_factor(i) = normal(rng);
  a.compliance_factor = Eigen::MatrixXd::Identity(n, n) * 1e-8;
  // mechanismOfEveryKind()[2]: a transmission_error of 2 harmonics, 4 coefficients.
  ASSERT_EQ(with.mechanisms[2].kind, MechanismKind::kTransmissionError);
  a.profile_factors.push_back({2, Eigen::MatrixXd(4, 2)});
  for (Eigen::Index i = 0; i < 8; ++i) a.profile_factors[0].factor(i) = normal(rng);
  with.accuracy = a;
  const std::vector<uint8_t> b = serializeModel(with);
  EXPECT_EQ(b.size(), bytes().size() + 16 + 4 + 16 + 8 + 6 * (n + 1) * 30 * 8 + 4 + n * n * 8 +
                          4 + 8 + 4 * 2 * 8);
  const CalibratedModel parsed = parse(b);
  ASSERT_TRUE(parsed.accuracy.has_value());
  EXPECT_EQ(parsed.accuracy->geometry_factor, a.geometry_factor);
  EXPECT_EQ(parsed.accuracy->compliance_factor, a.compliance_factor);
  ASSERT_EQ(parsed.accuracy->profile_factors.size(), 1u);
  EXPECT_EQ(parsed.accuracy->profile_factors[0].mechanism, 2u);
  EXPECT_EQ(parsed.accuracy->profile_factors[0].factor, a.profile_factors[0].factor);
  EXPECT_EQ(parsed.accuracy->position_noise_m, a.position_noise_m);
  EXPECT_EQ(parsed.accuracy->orientation_noise_rad, a.orientation_noise_rad);
  EXPECT_EQ(serializeModel(parsed), b);
  EXPECT_FALSE(parse(bytes()).accuracy.has_value());  // a file without ACCU loads as before

  const size_t accu = payloadOf(b, "ACCU");
  const auto refusedNaming = [&](size_t at, auto put, const std::string& field) {
    std::vector<uint8_t> edited = b;
    put(edited, at);
    refix(edited);
    const std::string message = refusal(edited);
    EXPECT_NE(message.find(field), std::string::npos) << message;
  };
  refusedNaming(accu, [](auto& e, size_t at) { putU32(e, at, 1); }, "accuracy.layout_version");
  refusedNaming(accu, [](auto& e, size_t at) { putU32(e, at, 3); }, "accuracy.layout_version");
  refusedNaming(accu + 4, [](auto& e, size_t at) { putF64(e, at, -1.0); },
                "accuracy.position_noise_m");
  refusedNaming(accu + 20, [](auto& e, size_t at) { putU32(e, at, 7); }, "accuracy.geometry_rows");
  refusedNaming(accu + 24, [](auto& e, size_t at) { putU32(e, at, 43); },
                "accuracy.geometry_rank");
  refusedNaming(accu + 28 + 8 * 31, [](auto& e, size_t at) { putF64(e, at, std::nan("")); },
                "accuracy.geometry_factor(1, 1): nan");
  refusedNaming(accu + 28 + 8 * 6 * (n + 1) * 30, [](auto& e, size_t at) { putU32(e, at, 2); },
                "accuracy.compliance_count");
  const size_t profiles = accu + 28 + 8 * 6 * (n + 1) * 30 + 4 + 8 * n * n;
  refusedNaming(profiles, [](auto& e, size_t at) { putU32(e, at, 99); }, "accuracy.profile_count");
  refusedNaming(profiles + 4, [](auto& e, size_t at) { putU32(e, at, 0); },  // a backlash
                "accuracy.profile_factors[0].mechanism");
  refusedNaming(profiles + 8, [](auto& e, size_t at) { putU32(e, at, 5); },
                "accuracy.profile_factors[0].rank");
  refusedNaming(profiles + 12 + 8, [](auto& e, size_t at) { putF64(e, at, std::nan("")); },
                "accuracy.profile_factors[0].factor(0, 1): nan");

  CalibratedModel not_a_profile = with;
  not_a_profile.accuracy->profile_factors[0].mechanism = 0;
  EXPECT_THROW(serializeModel(not_a_profile), InputError);
  CalibratedModel too_wide = with;
  too_wide.accuracy->profile_factors[0].factor.resize(4, 5);
  EXPECT_THROW(serializeModel(too_wide), InputError);
  with.accuracy->compliance_factor.resize(2, 2);
  EXPECT_THROW(serializeModel(with), InputError);
}

// A bad reference force is refused at load with the field, the value read and what was expected;
// a reference > 0 on a GPR whose inputs cannot hold the wrench (fewer than six) is refused too.
TEST_F(ModelFileTest, ABadPayloadForceReferenceIsRefusedWithItsValue) {
  CalibratedModel per_force = model();
  per_force.gpr->payload_force_reference_n = 294.2;
  const std::vector<uint8_t> b = serializeModel(per_force);
  const size_t reference_at = payloadOf(b, "PROV") - 16 - 8;
  ASSERT_EQ(getF64(b, reference_at), 294.2);
  const std::vector<std::pair<double, std::string>> bad = {
      {-3.0, "-3; expected > 0"},
      {0.0, "0; expected > 0"},
      {std::nan(""), "nan; expected a finite number"},
      {std::numeric_limits<double>::infinity(), "inf; expected a finite number"}};
  for (const auto& [value, said] : bad) {
    std::vector<uint8_t> edited = b;
    putF64(edited, reference_at, value);
    refix(edited);
    const std::string message = refusal(edited);
    EXPECT_NE(message.find("byte " + std::to_string(reference_at) +
                           ", gpr.payload_force_reference_n: " + said),
              std::string::npos)
        << message;
  }
  std::mt19937_64 rng(8);
  CalibratedModel few_inputs = model();
  few_inputs.gpr = randomGpr(rng, 20, 5, 3);
  few_inputs.gpr->payload_force_reference_n = 300.0;
  try {
    serializeModel(few_inputs);
    ADD_FAILURE() << "a reference force with 5 inputs was written";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("gpr.payload_force_reference_n is 300 with D = 5"),
              std::string::npos)
        << e.what();
  }
}

TEST_F(ModelFileTest, IllConditionedButConsistentGprIsAccepted) {
  // Long length scales and σ_f/σ_n = 1e6: α from Cholesky leaves ‖(K + σ_n² I) α − Y‖ / ‖Y‖
  // around 1e-3, yet it is the exact solution to working precision (backward error ~1e-16).
  std::mt19937_64 rng(5);
  CalibratedModel ill = model();
  ill.gpr = randomGpr(rng, 300, 12, 6, 100.0, 100.0, 1e-4);
  const GprParameters& g = *ill.gpr;
  const Eigen::MatrixXd K = kernel(g.inputs_normalised, g.length_scales, g.signal_sigma) +
                            g.noise_sigma * g.noise_sigma * Eigen::MatrixXd::Identity(300, 300);
  EXPECT_GT((K * g.alpha - g.targets_standardised).norm() / g.targets_standardised.norm(), 1e-6);
  const std::vector<uint8_t> b = serializeModel(ill);
  expectSameModel(ill, parse(b));
}

TEST_F(ModelFileTest, FileRoundTripReplacesAtomicallyAndLeavesNoTemporary) {
  const ScratchFolder folder;
  const std::string path = (folder.path() / "irb4400.stepcal").string();
  writeModelFile(model(), path);
  expectSameModel(model(), readModelFile(path));
  EXPECT_EQ(fs::file_size(path), bytes().size());

  CalibratedModel other = model();
  other.gpr.reset();
  other.provenance.trainer_version = "stepcal 0.2.0";
  writeModelFile(other, path);
  expectSameModel(other, readModelFile(path));
  EXPECT_EQ(folder.entries(), std::vector<std::string>{"irb4400.stepcal"});
}

// A write past the file size limit raises SIGXFSZ, which ends a process by default; the writer
// holds it back, reports the EFBIG and leaves the previous file alone.
TEST_F(ModelFileTest, WritePastTheFileSizeLimitLeavesThePreviousFile) {
  const ScratchFolder folder;
  const std::string path = (folder.path() / "irb4400.stepcal").string();
  writeModelFile(model(), path);
  rlimit previous{};
  ASSERT_EQ(getrlimit(RLIMIT_FSIZE, &previous), 0);
  rlimit small = previous;
  small.rlim_cur = 4096;
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &small), 0);
  std::string message;
  try {
    writeModelFile(model(), path);
  } catch (const InputError& e) {
    message = e.what();
  }
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &previous), 0);
  EXPECT_NE(message.find(path + ": cannot write the model: writing " + path + ".tmp-"),
            std::string::npos)
      << message;
  EXPECT_NE(message.find("(File too large); the previous file, if any, is unchanged"),
            std::string::npos)
      << message;
  EXPECT_NE(message.find("hint: raise the file size limit (ulimit -f)"), std::string::npos)
      << message;
  EXPECT_EQ(folder.entries(), std::vector<std::string>{"irb4400.stepcal"});
  expectSameModel(model(), readModelFile(path));
}

TEST_F(ModelFileTest, WriteRefusesMissingFolderAndReadRefusesMissingFile) {
  const ScratchFolder folder;
  const std::string path = (folder.path() / "no_such_folder" / "m.stepcal").string();
  try {
    writeModelFile(model(), path);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
  }
  EXPECT_THROW(readModelFile(path), InputError);
  EXPECT_THROW(readModelFile(folder.path().string()), InputError);  // a folder, not a file
  EXPECT_TRUE(folder.entries().empty());
}

TEST_F(ModelFileTest, EveryFlippedBitIsRefused) {
  std::vector<uint8_t> b = bytes();
  const auto start = std::chrono::steady_clock::now();
  size_t accepted = 0;
  for (size_t at = 0; at < b.size(); ++at) {
    const uint8_t mask = uint8_t(1u << (at % 8));
    b[at] ^= mask;
    if (refusal(b).empty()) {
      ++accepted;
      ADD_FAILURE() << "flipping bit " << at % 8 << " of byte " << at << " was not noticed";
    }
    b[at] ^= mask;
  }
  EXPECT_EQ(accepted, 0u);
  std::cout << "[          ] " << b.size() << " bit flips checked in "
            << std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()
            << " s\n";
}

TEST_F(ModelFileTest, EveryTruncationAndExtensionIsRefused) {
  const std::vector<uint8_t>& b = bytes();
  for (size_t length = 0; length < b.size(); ++length) {
    EXPECT_THROW(parseModel(b.data(), length, "truncated.model"), InputError) << length;
  }
  std::vector<uint8_t> longer = b;
  longer.push_back(0);
  EXPECT_NE(refusal(longer).find("truncated or extended"), std::string::npos);
  EXPECT_NE(refusal(std::vector<uint8_t>(b.begin(), b.end() - 1)).find("truncated or extended"),
            std::string::npos);
}

TEST_F(ModelFileTest, ChecksumMismatchSaysCorrupted) {
  std::vector<uint8_t> b = bytes();
  b[b.size() / 2] ^= 0x10;
  const std::string message = refusal(b);
  EXPECT_NE(message.find("corrupted"), std::string::npos) << message;
  EXPECT_EQ(message.rfind("test.model: byte ", 0), 0u) << message;
}

TEST_F(ModelFileTest, VersionMismatchNamesBothVersionsAndTheCommandToRerun) {
  EXPECT_EQ(getU32(bytes(), 8), 4u);
  for (const uint32_t version : {1u, 2u, 3u, 5u}) {
    std::vector<uint8_t> b = bytes();
    putU32(b, 8, version);
    refix(b);
    const std::string message = refusal(b);
    EXPECT_EQ(message.rfind("test.model: byte 8, version: model format version " +
                                std::to_string(version) + ", this build reads 4",
                            0),
              0u)
        << message;
    EXPECT_NE(message.find("hint: re-run `stepcal calibrate`"), std::string::npos) << message;
  }
}

TEST_F(ModelFileTest, VersionOneFileWithoutMechanismsIsRefusedNotRead) {
  // What the previous build wrote: the same sections without MECH, version 1.
  std::vector<uint8_t> b = bytes();
  const size_t mech = payloadOf(b, "MECH") - 16;
  const size_t gpr = payloadOf(b, "GPR ") - 16;
  b.erase(b.begin() + long(mech), b.begin() + long(gpr));
  putU32(b, 8, 1);
  refix(b);
  const std::string message = refusal(b);
  EXPECT_NE(message.find("byte 8, version: model format version 1, this build reads 4"),
            std::string::npos)
      << message;
  EXPECT_NE(message.find("re-run `stepcal calibrate`"), std::string::npos) << message;
}

TEST_F(ModelFileTest, BadMagicIsNotAModelFile) {
  std::vector<uint8_t> b = bytes();
  b[0] = 'X';
  refix(b);
  EXPECT_NE(refusal(b).find("not a stepcal model file"), std::string::npos);
  const std::string text = "solver: lm\n";
  EXPECT_NE(refusal(std::vector<uint8_t>(text.begin(), text.end())).find("not a stepcal model"),
            std::string::npos);
  EXPECT_NE(refusal({}).find("not a stepcal model file"), std::string::npos);
}

TEST_F(ModelFileTest, NonFiniteValueIsRefusedWithItsField) {
  std::vector<uint8_t> b = bytes();
  const size_t at = gprInputsAt(b, 12, 6) + 8 * (12 * 7 + 3);  // inputs_normalised(7, 3)
  ASSERT_EQ(getF64(b, at), model().gpr->inputs_normalised(7, 3));
  putF64(b, at, std::numeric_limits<double>::quiet_NaN());
  refix(b);
  const std::string message = refusal(b);
  EXPECT_NE(message.find("byte " + std::to_string(at) + ", gpr.inputs_normalised(7, 3): nan; "
                         "expected a finite number"),
            std::string::npos)
      << message;
}

TEST_F(ModelFileTest, NonOrthonormalRotationIsRefused) {
  std::vector<uint8_t> b = bytes();
  const size_t at = payloadOf(b, "REGI");  // X_TrackerBase R(0, 0)
  ASSERT_EQ(getF64(b, at), model().X_TrackerBase.linear()(0, 0));
  putF64(b, at, getF64(b, at) * (1 + 1e-6));
  refix(b);
  const std::string message = refusal(b);
  EXPECT_NE(message.find("registration.X_TrackerBase: rotation is not orthonormal"),
            std::string::npos)
      << message;
}

TEST_F(ModelFileTest, ReflectionIsRefused) {
  std::vector<uint8_t> b = bytes();
  const size_t at = payloadOf(b, "REGI");
  for (int c = 0; c < 3; ++c) putF64(b, at + 8 * size_t(c), -getF64(b, at + 8 * size_t(c)));
  refix(b);
  EXPECT_NE(refusal(b).find("determinant"), std::string::npos);
}

TEST_F(ModelFileTest, InconsistentAlphaIsRefused) {
  std::vector<uint8_t> b = bytes();
  const size_t alpha_at = gprInputsAt(b, 12, 6) + 8 * 300 * (12 + 6);
  const size_t at = alpha_at + 8 * (6 * 150 + 2);  // α(150, 2)
  ASSERT_EQ(getF64(b, at), model().gpr->alpha(150, 2));
  putF64(b, at, getF64(b, at) * (1 + 1e-5));
  refix(b);
  const std::string message = refusal(b);
  EXPECT_NE(message.find("byte " + std::to_string(alpha_at) + ", gpr.alpha"), std::string::npos)
      << message;
  EXPECT_NE(message.find("inconsistent"), std::string::npos) << message;

  // A changed hyperparameter makes the stored α wrong as well.
  b = bytes();
  const size_t noise_at = gprInputsAt(b, 12, 6) - 8;
  ASSERT_EQ(getF64(b, noise_at), model().gpr->noise_sigma);
  putF64(b, noise_at, 0.09);
  refix(b);
  EXPECT_NE(refusal(b).find("inconsistent"), std::string::npos);
}

TEST_F(ModelFileTest, SensorFrameOutOfRangeIsRefused) {
  std::vector<uint8_t> b = bytes();
  const size_t at = payloadOf(b, "REGI") + 8 * (12 + 3);
  ASSERT_EQ(int(getU32(b, at)), model().sensor_frame);
  putU32(b, at, 3);
  refix(b);
  const std::string message = refusal(b);
  EXPECT_NE(message.find("registration.sensor_frame: 3; expected −1 (no sensor) or 0 … 1"),
            std::string::npos)
      << message;
}

TEST_F(ModelFileTest, OtherSemanticChecks) {
  const auto edited = [&](auto edit) {
    std::vector<uint8_t> b = bytes();
    edit(b);
    refix(b);
    return refusal(b);
  };
  const size_t chain = payloadOf(bytes(), "CHAN");
  const size_t name0 = getU32(bytes(), chain + 4);
  const size_t twist0 = chain + 4 + 4 + name0;
  EXPECT_NE(edited([&](auto& b) { putF64(b, twist0 + 40, 1.001); }).find("rotation axis has norm"),
            std::string::npos);
  EXPECT_NE(edited([&](auto& b) { putU32(b, chain, 0); }).find("chain.dof: 0; expected 1 … 8"),
            std::string::npos);
  EXPECT_NE(edited([&](auto& b) { putU32(b, chain, 9); }).find("chain.dof: 9; expected 1 … 8"),
            std::string::npos);
  EXPECT_NE(edited([&](auto& b) { putU32(b, chain + 4, 5000); }).find("at most 4096"),
            std::string::npos);
  EXPECT_NE(edited([&](auto& b) { putF64(b, twist0 + 48, 4.0); }).find("expected lower ≤ upper"),
            std::string::npos);
  EXPECT_NE(edited([&](auto& b) { putF64(b, twist0 + 48, std::nan("")); })
                .find("chain.joints[0].lower_rad: nan"),
            std::string::npos);
  EXPECT_NE(edited([&](auto& b) {
              putF64(b, twist0 + 48, std::numeric_limits<double>::infinity());
              putF64(b, twist0 + 56, std::numeric_limits<double>::infinity());
            }).find("expected lower ≤ upper"),
            std::string::npos);
  const size_t compliance = payloadOf(bytes(), "COMP");
  EXPECT_NE(edited([&](auto& b) { putF64(b, compliance + 4 + 8, -1e-6); })
                .find("compliance.compliance_rad_per_nm[1]: -1e-06; expected ≥ 0"),
            std::string::npos);
  EXPECT_NE(edited([&](auto& b) { putU32(b, compliance, 5); }).find("compliance.count"),
            std::string::npos);
  const size_t gpr = payloadOf(bytes(), "GPR ");
  EXPECT_NE(edited([&](auto& b) { putF64(b, gpr + 12 + 8 * 12, 0.0); })
                .find("gpr.input_scale[0]: 0; expected > 0"),
            std::string::npos);
  EXPECT_NE(edited([&](auto& b) { putU32(b, gpr + 4, 65); }).find("gpr.m/D/P"),
            std::string::npos);
  EXPECT_NE(edited([&](auto& b) { putU32(b, gpr, 299); }).find("payload has"),
            std::string::npos);
  // Swapping the order of two sections is a structural error even with a valid checksum.
  EXPECT_NE(edited([&](auto& b) { std::memcpy(&b[chain - 16], "REGI", 4); })
                .find("expected the sections CHAN, NOMI, REGI, COMP, MECH, GPR, PROV (then ACCU, "
                      "optional) in that order"),
            std::string::npos);
  EXPECT_NE(edited([&](auto& b) { putU32(b, chain - 12, 1); }).find("reserved word"),
            std::string::npos);
  EXPECT_NE(edited([&](auto& b) { putU32(b, 12, 4); }).find("flags"), std::string::npos);
  const size_t provenance = payloadOf(bytes(), "PROV");
  EXPECT_NE(edited([&](auto& b) { b[provenance + 4] = 'g'; }).find("hexadecimal"),
            std::string::npos);
}

TEST_F(ModelFileTest, NominalChainFollowsTheCalibratedChainAndDescribesTheSameRobot) {
  // NOMI comes right after CHAN: the CHAN payload, then NOMI's 16-byte section header.
  const std::vector<uint8_t>& b = bytes();
  const size_t chain = payloadOf(b, "CHAN");
  uint64_t chain_length = 0;
  for (int i = 0; i < 8; ++i) chain_length |= uint64_t(b[chain - 8 + size_t(i)]) << (8 * i);
  const size_t nominal = payloadOf(b, "NOMI");
  EXPECT_EQ(nominal, chain + chain_length + 16);
  EXPECT_EQ(std::memcmp(&b[nominal - 16], "NOMI", 4), 0);

  const auto edited = [&](auto edit) {
    std::vector<uint8_t> e = bytes();
    edit(e);
    refix(e);
    return refusal(e);
  };
  const std::string fewer = edited([&](auto& e) { putU32(e, nominal, 5); });
  EXPECT_NE(fewer.find("byte " + std::to_string(nominal) +
                       ", nominal.dof: 5; expected 6, the calibrated chain's"),
            std::string::npos)
      << fewer;
  const std::string name0 = model().nominal_Base.joints()[0].name;
  ASSERT_EQ(getU32(b, nominal + 4), name0.size());
  const std::string renamed = edited([&](auto& e) { e[nominal + 8] ^= 0x20; });
  EXPECT_NE(renamed.find("byte " + std::to_string(nominal + 4) + ", nominal.joints[0].name: '"),
            std::string::npos)
      << renamed;
  EXPECT_NE(renamed.find("expected '" + name0 + "', the calibrated chain's joint 1"),
            std::string::npos)
      << renamed;
  // The nominal chain is checked like the calibrated one.
  const size_t twist0 = nominal + 4 + 4 + name0.size();
  EXPECT_NE(edited([&](auto& e) { putF64(e, twist0 + 40, 1.001); })
                .find("nominal.joints[0].twist_Local: rotation axis has norm"),
            std::string::npos);
}

TEST_F(ModelFileTest, MechanismsOfEveryKindRoundTripBetweenCompliancesAndGpr) {
  const CalibratedModel parsed = parse(bytes());
  ASSERT_EQ(parsed.mechanisms.size(), 12u);
  for (size_t i = 0; i < parsed.mechanisms.size(); ++i) {
    EXPECT_EQ(parsed.mechanisms[i].kind, model().mechanisms[i].kind) << i;
  }
  // MECH follows COMP and precedes GPR, each with its 16-byte section header.
  const std::vector<uint8_t>& b = bytes();
  const size_t compliance = payloadOf(b, "COMP");
  const size_t mech = payloadOf(b, "MECH");
  EXPECT_EQ(mech, compliance + 4 + 2 * 8 * 6 + 16);
  EXPECT_EQ(getU32(b, mech), 12u);
  // Record by record: header, parameters, sigmas, coverage (arc count, arcs, fade);
  // 4 + Σ (20 + 16 p + 4 + 16 a + 8) bytes in all.
  size_t length = 4;
  for (size_t i = 0; i < 12; ++i) {
    const Mechanism& m = model().mechanisms[i];
    const size_t at = mechanismAt(b, i);
    EXPECT_EQ(getU32(b, at), static_cast<uint32_t>(m.kind));
    EXPECT_EQ(int32_t(getU32(b, at + 4)), m.joint);
    EXPECT_EQ(int32_t(getU32(b, at + 8)), m.source_joint);
    EXPECT_EQ(int32_t(getU32(b, at + 12)), m.order);
    ASSERT_EQ(getU32(b, at + 16), m.parameters.size());
    for (size_t k = 0; k < m.parameters.size(); ++k) {
      EXPECT_EQ(getF64(b, at + 20 + 8 * k), m.parameters[k]);
      EXPECT_EQ(getF64(b, at + 20 + 8 * (m.parameters.size() + k)), m.sigma[k]);
    }
    const size_t coverage = at + 20 + 16 * m.parameters.size();
    ASSERT_EQ(2 * size_t(getU32(b, coverage)), m.coverage.arcs_rad.size());
    for (size_t k = 0; k < m.coverage.arcs_rad.size(); ++k) {
      EXPECT_EQ(getF64(b, coverage + 4 + 8 * k), m.coverage.arcs_rad[k]);
    }
    EXPECT_EQ(getF64(b, coverage + 4 + 8 * m.coverage.arcs_rad.size()), m.coverage.fade_rad);
    length += 20 + 16 * m.parameters.size() + 4 + 8 * m.coverage.arcs_rad.size() + 8;
  }
  // The transmission profile carries its coverage; the other kinds none.
  EXPECT_FALSE(model().mechanisms[2].coverage.arcs_rad.empty());
  EXPECT_EQ(payloadOf(b, "GPR "), mech + length + 16);
  // No mechanisms: an empty MECH (its count alone).
  CalibratedModel none = model();
  none.mechanisms.clear();
  const std::vector<uint8_t> without = serializeModel(none);
  EXPECT_EQ(getU32(without, payloadOf(without, "MECH")), 0u);
  EXPECT_EQ(payloadOf(without, "GPR "), payloadOf(without, "MECH") + 4 + 16);
  expectSameModel(none, parse(without));
}

TEST_F(ModelFileTest, EachMalformedMechanismIsRefusedWithItsOffsetIndexAndProblem) {
  const auto edited = [&](auto edit) {
    std::vector<uint8_t> b = bytes();
    edit(b);
    refix(b);
    return refusal(b);
  };
  // Each edit, the byte offset and field the message must name, and the problem it must state.
  struct Case {
    std::function<void(std::vector<uint8_t>&)> edit;
    size_t at;
    std::string field, problem;
  };
  const std::vector<uint8_t>& b = bytes();
  const size_t backlash = mechanismAt(b, 0), transmission = mechanismAt(b, 2),
               nonlinear = mechanismAt(b, 3), coupling = mechanismAt(b, 6);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<Case> cases = {
      {[&](auto& e) { putU32(e, backlash, 16); }, backlash, "mechanisms[0]",
       "mechanism kind 16; expected 1 to 15"},
      {[&](auto& e) { putU32(e, backlash + 4, 6); }, backlash, "mechanisms[0]",
       "backlash joint index 6; expected 0 to 5"},
      {[&](auto& e) { putU32(e, backlash + 4, uint32_t(-1)); }, backlash, "mechanisms[0]",
       "backlash joint index -1; expected 0 to 5"},
      {[&](auto& e) { putU32(e, transmission + 12, 0); }, transmission, "mechanisms[2]",
       "transmission_error order 0; expected 1 to 64 harmonics"},
      {[&](auto& e) { putU32(e, transmission + 12, 1); }, transmission, "mechanisms[2]",
       "transmission_error has 4 parameters and 4 sigmas; expected 2"},
      {[&](auto& e) { putU32(e, transmission, uint32_t(MechanismKind::kJointCoupling)); }, transmission,
       "mechanisms[2]", "joint_coupling order 2; expected 1 to 64 harmonics for transmission_error"},
      {[&](auto& e) { putF64(e, transmission + 20 + 64 + 4 + 8, 0.0); }, transmission,
       "mechanisms[2]", "coverage arc 0 (start 1 rad, length 0 rad); expected start in [0, 2pi)"},
      {[&](auto& e) { putF64(e, transmission + 20 + 64 + 4, 7.0); }, transmission,
       "mechanisms[2]", "coverage arc 0 (start 7 rad"},
      {[&](auto& e) { putF64(e, transmission + 20 + 64 + 4 + 16, -0.1); }, transmission,
       "mechanisms[2]", "coverage fade -0.1"},
      {[&](auto& e) { putF64(e, nonlinear + 20 + 8, 0.0); }, nonlinear, "mechanisms[3]",
       "nonlinear_stiffness saturation_torque_nm"},
      {[&](auto& e) { putF64(e, nonlinear + 20 + 16, -1.0); }, nonlinear, "mechanisms[3]",
       "nonlinear_stiffness linear_above_nm = -1"},
      {[&](auto& e) { putU32(e, coupling + 8, 5); }, coupling, "mechanisms[6]",
       "joint_coupling source joint index 5; expected a joint other than the moved one"},
      {[&](auto& e) { putF64(e, backlash + 20 + 16, -1e-5); }, backlash, "mechanisms[0]",
       "expected finite values, σ ≥ 0"},
      {[&](auto& e) { putF64(e, backlash + 20, nan); }, backlash + 20, "mechanisms[0].parameters[0]",
       "nan; expected a finite number"},
      {[&](auto& e) { putU32(e, backlash + 16, 1000); }, backlash + 16,
       "mechanisms[0].parameter_count", "1000; expected 0 … 128"},
      {[&](auto& e) { putU32(e, payloadOf(e, "MECH"), 65); }, payloadOf(b, "MECH"),
       "mechanisms.count", "65; expected 0 … 64"},
  };
  for (const Case& c : cases) {
    const std::string message = edited(c.edit);
    EXPECT_NE(message.find("test.model: byte " + std::to_string(c.at) + ", " + c.field + ": "),
              std::string::npos)
        << message;
    EXPECT_NE(message.find(c.problem), std::string::npos) << message;
  }
}

/// The bytes with a copy of mechanism record i appended to MECH (count and length updated,
/// checksum re-fixed), and where the copy starts.
std::pair<std::vector<uint8_t>, size_t> withRecordRepeated(const std::vector<uint8_t>& bytes,
                                                           size_t i) {
  std::vector<uint8_t> b = bytes;
  const size_t mech = payloadOf(b, "MECH");
  const uint32_t count = getU32(b, mech);
  const size_t from = mechanismAt(b, i), to = mechanismAt(b, i + 1), end = mechanismAt(b, count);
  const std::vector<uint8_t> record(b.begin() + long(from), b.begin() + long(to));
  b.insert(b.begin() + long(end), record.begin(), record.end());
  putU32(b, mech, count + 1);
  uint64_t length = 0;
  for (int k = 0; k < 8; ++k) length |= uint64_t(b[mech - 8 + size_t(k)]) << (8 * k);
  length += record.size();
  for (int k = 0; k < 8; ++k) b[mech - 8 + size_t(k)] = uint8_t(length >> (8 * k));
  refix(b);
  return {b, end};
}

TEST_F(ModelFileTest, MechanismsThatCannotBeTogetherOrLackTheirInputsAreRefused) {
  // A second self_weight, sensor_bias, thermal_expansion or tool_mount_compliance.
  for (const auto& [index, kind] : {std::pair{size_t(1), std::string("self_weight")},
                                    std::pair{size_t(4), std::string("thermal_expansion")},
                                    std::pair{size_t(5), std::string("sensor_bias")},
                                    std::pair{size_t(11), std::string("tool_mount_compliance")}}) {
    const auto [b, at] = withRecordRepeated(bytes(), index);
    const std::string message = refusal(b);
    EXPECT_NE(message.find("byte " + std::to_string(at) + ", mechanisms[12]: a second " + kind +
                           " (the first is mechanisms[" + std::to_string(index) +
                           "]); expected at most one"),
              std::string::npos)
        << message;
  }
  // A second backlash is another joint's or adds to the first: allowed.
  EXPECT_EQ(refusal(withRecordRepeated(bytes(), 0).first), "");
  // A second profile, profile geometry, torsion curve or zero drift of the same joint.
  for (const auto& [index, kind, joint] :
       {std::tuple{size_t(2), std::string("transmission_error"), 3},
        std::tuple{size_t(7), std::string("profile_geometry"), 3},
        std::tuple{size_t(8), std::string("torsion_curve"), 5},
        std::tuple{size_t(9), std::string("joint_zero_drift"), 2},
        std::tuple{size_t(10), std::string("off_axis_compliance"), 1}}) {
    const auto [b, at] = withRecordRepeated(bytes(), index);
    const std::string message = refusal(b);
    EXPECT_NE(message.find("byte " + std::to_string(at) + ", mechanisms[12]: a second " + kind +
                           " of joint " + std::to_string(joint) + " (the first is mechanisms[" +
                           std::to_string(index) +
                           "]); expected at most one per joint"),
              std::string::npos)
        << message;
  }
  // A profile geometry whose joint has no profile.
  {
    std::vector<uint8_t> b = bytes();
    putU32(b, mechanismAt(b, 7) + 4, 4);
    refix(b);
    const std::string message = refusal(b);
    EXPECT_NE(message.find("byte " + std::to_string(mechanismAt(b, 7)) +
                           ", mechanisms[7]: profile_geometry of joint 5 without a "
                           "transmission_error of that joint"),
              std::string::npos)
        << message;
  }

  // sensor_bias without a sensor frame, self_weight without gravity.
  std::vector<uint8_t> b = bytes();
  const size_t registration = payloadOf(b, "REGI");
  putU32(b, registration + 8 * 15, uint32_t(-1));
  refix(b);
  std::string message = refusal(b);
  EXPECT_NE(message.find("byte " + std::to_string(mechanismAt(b, 5)) +
                         ", mechanisms[5]: sensor_bias in a model without a sensor frame"),
            std::string::npos)
      << message;
  b = bytes();
  for (size_t k = 0; k < 3; ++k) putF64(b, registration + 8 * (12 + k), 0.0);
  refix(b);
  message = refusal(b);
  EXPECT_NE(message.find("byte " + std::to_string(mechanismAt(b, 1)) +
                         ", mechanisms[1]: self_weight in a model whose gravity is zero"),
            std::string::npos)
      << message;
}

TEST_F(ModelFileTest, SerialiseRefusesWhatTheLoaderWouldRefuse) {
  CalibratedModel bad = model();
  bad.compliance_rad_per_nm(2) = -1;
  EXPECT_THROW(serializeModel(bad), InputError);
  bad = model();
  bad.compliance_sigma_rad_per_nm.resize(3);
  EXPECT_THROW(serializeModel(bad), InputError);
  bad = model();
  bad.gpr->alpha.conservativeResize(299, 6);
  EXPECT_THROW(serializeModel(bad), InputError);
  bad = model();
  bad.gravity_Base.x() = std::numeric_limits<double>::infinity();
  EXPECT_THROW(serializeModel(bad), InputError);
  bad = model();
  bad.nominal_Base = KinematicChain();  // no nominal chain
  EXPECT_THROW(serializeModel(bad), InputError);
  bad = model();
  std::vector<ChainJoint> joints = bad.nominal_Base.joints();
  joints[3].name = "wrist_1";
  bad.nominal_Base =
      KinematicChain(joints, bad.nominal_Base.initialPoses(), bad.nominal_Base.frames());
  EXPECT_THROW(serializeModel(bad), InputError);
  bad = model();
  bad.mechanisms[0].sigma.push_back(0.0);  // the layout has one count for both
  EXPECT_THROW(serializeModel(bad), InputError);
  bad = model();
  bad.mechanisms[2].order = 0;
  EXPECT_THROW(serializeModel(bad), InputError);
  bad = model();
  bad.mechanisms[2].coverage.fade_rad = 0.0;
  EXPECT_THROW(serializeModel(bad), InputError);
  bad = model();
  bad.mechanisms[0].coverage = {{0.0, 1.0}, 0.1};  // backlash has no coverage
  EXPECT_THROW(serializeModel(bad), InputError);
  bad = model();
  bad.mechanisms.push_back(bad.mechanisms[4]);  // a second thermal_expansion
  EXPECT_THROW(serializeModel(bad), InputError);
  bad = model();
  bad.mechanisms.assign(kMaxMechanisms + 1, model().mechanisms[0]);
  EXPECT_THROW(serializeModel(bad), InputError);
  EXPECT_THROW(serializeModel(CalibratedModel{}), InputError);  // no chain
}

}  // namespace
}  // namespace stepcal
