// Model file writer and loader (layout in model_file.hpp).
//
// The loader treats the bytes as hostile: every read is bounds-checked against the current
// section, every count is bounded and matched against the bytes that remain before anything is
// allocated, and every value is checked where it is read, so an error names its byte offset.
#include "stepcal/common/model_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <new>
#include <system_error>
#include <utility>

#include "stepcal/common/atomic_file.hpp"
#include "stepcal/common/error.hpp"

namespace stepcal {
namespace {

static_assert(std::numeric_limits<double>::is_iec559, "the file stores IEEE-754 doubles");

constexpr std::array<uint8_t, 8> kMagic = {'S', 'T', 'E', 'P', 'C', 'A', 'L', '\0'};
constexpr size_t kHeaderBytes = 24;
constexpr size_t kCrcBytes = 4;
constexpr size_t kPoseDoubles = 12;

// Bounds on counts; they keep every allocation proportional to a plausible model.
constexpr uint32_t kMaxStringBytes = 4096;
constexpr uint32_t kMaxFrames = 64;
constexpr uint32_t kMaxValidationFigures = 1024;
/// The runtime factors an m × m kernel at load (3.2 GB at this bound); more is not usable.
constexpr uint32_t kMaxGprSamples = 20000;
constexpr uint32_t kMaxGprDims = 64;
/// The longest parameter layout of a mechanism: a transmission profile's 2 per harmonic (more
/// than self_weight's 4 per link).
constexpr uint32_t kMaxMechanismParameters = 2 * kMaxHarmonics;
static_assert(kMaxMechanismParameters >= 4 * kMaxJoints, "self_weight must fit");
static_assert(kMaxMechanismParameters >= 6 * (kMaxJoints + 1), "profile_geometry must fit");
/// Bytes of a mechanism record before its parameters: kind, joint, source_joint, order, p.
constexpr size_t kMechanismHeaderBytes = 5 * 4;

constexpr double kInfinity = std::numeric_limits<double>::infinity();
constexpr double kUnitTolerance = 1e-9;         ///< on |ω| − 1 and on RᵀR − I
/// On the normwise backward error of α, ‖(K + σ_n² I) α − Y‖ / (‖K + σ_n² I‖ ‖α‖ + ‖Y‖). A
/// Cholesky solve gives ~1e-16 however ill-conditioned K is; the residual relative to ‖Y‖ alone
/// reaches 1e-3 for legitimate fits (long length scales, σ_f/σ_n ≈ 1e6) and would refuse them.
constexpr double kAlphaBackwardErrorLimit = 1e-10;

constexpr uint32_t fourcc(const char (&s)[5]) {
  return uint32_t(uint8_t(s[0])) | uint32_t(uint8_t(s[1])) << 8 | uint32_t(uint8_t(s[2])) << 16 |
         uint32_t(uint8_t(s[3])) << 24;
}

struct SectionId {
  uint32_t tag;
  const char* name;
};
constexpr SectionId kChain{fourcc("CHAN"), "chain"};
constexpr SectionId kNominal{fourcc("NOMI"), "nominal chain"};
constexpr SectionId kRegistration{fourcc("REGI"), "registration"};
constexpr SectionId kCompliance{fourcc("COMP"), "compliance"};
constexpr SectionId kMechanisms{fourcc("MECH"), "mechanisms"};
constexpr SectionId kGpr{fourcc("GPR "), "gpr"};
constexpr SectionId kProvenance{fourcc("PROV"), "provenance"};
constexpr SectionId kAccuracy{fourcc("ACCU"), "accuracy"};

/// Bytes a GPR per payload force adds to its section: its reference force, N.
constexpr uint64_t kPayloadForceBytes = 8;
/// Payload bytes of a GPR section with m samples, D inputs and P outputs.
constexpr uint64_t gprPayloadBytes(uint64_t m, uint64_t D, uint64_t P) {
  return 12 + 8 * (3 * D + 2 * P + 2) + 8 * m * (D + 2 * P);
}

/// Largest file readModelFile accepts: every legal model fits (the GPR at its bounds dominates).
constexpr uint64_t kMaxFileBytes = 64ull << 20;
static_assert(gprPayloadBytes(kMaxGprSamples, kMaxGprDims, kMaxGprDims) + kPayloadForceBytes +
                      uint64_t(kMaxValidationFigures + 4) * (kMaxStringBytes + 64) +
                      uint64_t(kMaxMechanisms) *
                          (kMechanismHeaderBytes + 16 * kMaxMechanismParameters) +
                      2 * uint64_t(kMaxFrames + kMaxJoints) * (kMaxStringBytes + 8 * 20) <
                  kMaxFileBytes,
              "kMaxFileBytes must hold the largest legal model");

/// CRC-32 tables for slicing by 8: table[0] is the classic byte table, table[k] advances a
/// byte's contribution by k further bytes, so eight bytes are folded per step.
using CrcTables = std::array<std::array<uint32_t, 256>, 8>;
constexpr CrcTables makeCrcTables() {
  CrcTables t{};
  for (uint32_t i = 0; i < 256; ++i) {
    uint32_t c = i;
    for (int k = 0; k < 8; ++k) c = (c & 1u) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
    t[0][i] = c;
  }
  for (size_t k = 1; k < 8; ++k) {
    for (size_t i = 0; i < 256; ++i) t[k][i] = (t[k - 1][i] >> 8) ^ t[0][t[k - 1][i] & 0xFFu];
  }
  return t;
}
constexpr CrcTables kCrc = makeCrcTables();

std::string number(double v) {
  std::array<char, 32> buf{};
  const auto [end, ec] = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  return ec == std::errc() ? std::string(buf.data(), end) : std::string("?");
}

std::string hex32(uint32_t v) {
  std::array<char, 11> buf{};
  std::snprintf(buf.data(), buf.size(), "0x%08X", v);
  return buf.data();
}

/// A FourCC for messages: its characters when printable, else its hex value.
std::string tagText(uint32_t tag) {
  std::string s = "'";
  for (int i = 0; i < 4; ++i) {
    const char c = char((tag >> (8 * i)) & 0xFF);
    if (c < 0x20 || c > 0x7E) return hex32(tag);
    s += c;
  }
  return s + "'";
}

/// Printable text check: the strings end up in log lines and reports.
bool hasControlCharacter(const std::string& s) {
  for (const char c : s) {
    if (uint8_t(c) < 0x20 || uint8_t(c) == 0x7F) return true;
  }
  return false;
}

bool isHex(const std::string& s) {
  for (const char c : s) {
    if (!std::isxdigit(static_cast<unsigned char>(c))) return false;
  }
  return true;
}

// ---------------------------------------------------------------------------------------------
// Writing

class Writer {
 public:
  void u32(uint32_t v) { put(v, 4); }
  void i32(int32_t v) { put(uint32_t(v), 4); }
  void u64(uint64_t v) { put(v, 8); }
  void f64(double v) {
    uint64_t bits = 0;
    std::memcpy(&bits, &v, sizeof bits);
    put(bits, 8);
  }
  void str(const std::string& s) {
    u32(uint32_t(s.size()));
    out_.insert(out_.end(), s.begin(), s.end());
  }
  void pose(const Pose& X) {
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c) f64(X.matrix()(r, c));
    }
  }
  /// A chain as CHAN stores it.
  void chainPayload(const KinematicChain& chain) {
    u32(uint32_t(chain.dof()));
    for (const ChainJoint& j : chain.joints()) {
      str(j.name);
      for (int i = 0; i < 6; ++i) f64(j.twist_Local(i));
      f64(j.lower_rad);
      f64(j.upper_rad);
    }
    for (const Pose& X : chain.initialPoses()) pose(X);
    u32(uint32_t(chain.frames().size()));
    for (const AttachedFrame& f : chain.frames()) {
      str(f.name);
      u32(uint32_t(f.parent));
      pose(f.X_ParentFrame);
    }
  }
  template <typename Derived>
  void rowMajor(const Eigen::DenseBase<Derived>& M) {
    for (Eigen::Index r = 0; r < M.rows(); ++r) {
      for (Eigen::Index c = 0; c < M.cols(); ++c) f64(M(r, c));
    }
  }
  /// Starts a section; returns where its length goes.
  size_t beginSection(const SectionId& id) {
    u32(id.tag);
    u32(0);
    const size_t at = out_.size();
    u64(0);
    return at;
  }
  void endSection(size_t length_at) {
    const uint64_t length = out_.size() - length_at - 8;
    for (int i = 0; i < 8; ++i) out_[length_at + size_t(i)] = uint8_t(length >> (8 * i));
  }
  std::vector<uint8_t>& bytes() { return out_; }

 private:
  void put(uint64_t v, int bytes) {
    for (int i = 0; i < bytes; ++i) out_.push_back(uint8_t(v >> (8 * i)));
  }
  std::vector<uint8_t> out_;
};

/// Refuses accuracy factors of sizes the ACCU layout cannot express.
template <class Refuse>
void checkAccuracyWritable(const AccuracyFactors& a, int n, const std::vector<Mechanism>& mechanisms,
                           const Refuse& refuse) {
  const Eigen::Index g = a.geometry_factor.rows(), r = a.geometry_factor.cols();
  if (!((g == 0 && r == 0) || (g == 6 * (n + 1) && r <= g))) {
    refuse("accuracy.geometry_factor is " + std::to_string(g) + " × " + std::to_string(r) +
           "; expected 0 × 0 or " + std::to_string(6 * (n + 1)) + " × r, r ≤ " +
           std::to_string(6 * (n + 1)));
  }
  const Eigen::Index c = a.compliance_factor.rows();
  if (!((c == 0 || c == n) && a.compliance_factor.cols() == c)) {
    refuse("accuracy.compliance_factor is " + std::to_string(c) + " × " +
           std::to_string(a.compliance_factor.cols()) + "; expected 0 × 0 or " +
           std::to_string(n) + " × " + std::to_string(n));
  }
  for (size_t i = 0; i < a.profile_factors.size(); ++i) {
    const ProfileCovarianceFactor& p = a.profile_factors[i];
    const std::string field = "accuracy.profile_factors[" + std::to_string(i) + "]";
    if (p.mechanism >= mechanisms.size() ||
        mechanisms[p.mechanism].kind != MechanismKind::kTransmissionError ||
        (i > 0 && p.mechanism <= a.profile_factors[i - 1].mechanism)) {
      refuse(field + " is for mechanism " + std::to_string(p.mechanism) +
             "; expected a transmission_error's index, ascending");
    }
    const Eigen::Index rows = 2 * mechanisms[p.mechanism].order;
    if (p.factor.rows() != rows || p.factor.cols() > rows) {
      refuse(field + " is " + std::to_string(p.factor.rows()) + " × " +
             std::to_string(p.factor.cols()) + "; expected " + std::to_string(rows) + " × r, r ≤ " +
             std::to_string(rows));
    }
  }
}

/// Refuses models whose sizes the fixed layout cannot express; parseModel checks the rest.
void checkWritable(const CalibratedModel& model, const std::string& source) {
  const auto refuse = [&](const std::string& message) { throw InputError(message, source); };
  const auto checkString = [&](const std::string& s, const std::string& field) {
    if (s.size() > kMaxStringBytes) {
      refuse(field + " has " + std::to_string(s.size()) + " bytes; expected at most " +
             std::to_string(kMaxStringBytes));
    }
  };
  for (const auto& [chain, field] : {std::pair{&model.chain_Tracker, std::string("chain")},
                                      std::pair{&model.nominal_Base, std::string("nominal")}}) {
    for (const ChainJoint& j : chain->joints()) checkString(j.name, field + " joint name");
    if (chain->frames().size() > kMaxFrames) {
      refuse(field + " has " + std::to_string(chain->frames().size()) +
             " attached frames; expected at most " + std::to_string(kMaxFrames));
    }
    for (const AttachedFrame& f : chain->frames()) checkString(f.name, field + " frame name");
  }
  if (model.compliance_sigma_rad_per_nm.size() != model.compliance_rad_per_nm.size()) {
    refuse("compliance_sigma_rad_per_nm has " +
           std::to_string(model.compliance_sigma_rad_per_nm.size()) + " entries; expected " +
           std::to_string(model.compliance_rad_per_nm.size()) + " like compliance_rad_per_nm");
  }
  if (model.gpr) {
    const GprParameters& g = *model.gpr;
    const Eigen::Index m = g.inputs_normalised.rows(), D = g.inputs_normalised.cols(),
                       P = g.alpha.cols();
    if (m < 1 || m > kMaxGprSamples || D < 1 || D > kMaxGprDims || P < 1 || P > kMaxGprDims) {
      refuse("gpr has m = " + std::to_string(m) + ", D = " + std::to_string(D) + ", P = " +
             std::to_string(P) + "; expected 1 … " + std::to_string(kMaxGprSamples) +
             " samples and 1 … " + std::to_string(kMaxGprDims) + " inputs and outputs");
    }
    const auto checkSize = [&](Eigen::Index rows, Eigen::Index cols, Eigen::Index want_rows,
                               Eigen::Index want_cols, const char* field) {
      if (rows != want_rows || cols != want_cols) {
        refuse(std::string("gpr.") + field + " is " + std::to_string(rows) + " × " +
               std::to_string(cols) + "; expected " + std::to_string(want_rows) + " × " +
               std::to_string(want_cols) + " (m = " + std::to_string(m) + ", D = " +
               std::to_string(D) + ", P = " + std::to_string(P) + ")");
      }
    };
    checkSize(g.input_offset.size(), 1, D, 1, "input_offset");
    checkSize(g.input_scale.size(), 1, D, 1, "input_scale");
    checkSize(g.length_scales.size(), 1, D, 1, "length_scales");
    checkSize(g.output_mean.size(), 1, P, 1, "output_mean");
    checkSize(g.output_scale.size(), 1, P, 1, "output_scale");
    checkSize(g.targets_standardised.rows(), g.targets_standardised.cols(), m, P,
              "targets_standardised");
    checkSize(g.alpha.rows(), g.alpha.cols(), m, P, "alpha");
    if (!(std::isfinite(g.payload_force_reference_n) && g.payload_force_reference_n >= 0.0) ||
        (g.payload_force_reference_n > 0.0 && D < 6)) {
      refuse("gpr.payload_force_reference_n is " + number(g.payload_force_reference_n) +
             " with D = " + std::to_string(D) +
             "; expected 0 (the paper's GPR) or a finite force > 0 N with D ≥ 6");
    }
  }
  if (model.mechanisms.size() > kMaxMechanisms) {
    refuse("the model has " + std::to_string(model.mechanisms.size()) +
           " mechanisms; expected at most " + std::to_string(kMaxMechanisms));
  }
  for (size_t i = 0; i < model.mechanisms.size(); ++i) {
    const Mechanism& m = model.mechanisms[i];
    if (m.parameters.size() != m.sigma.size() || m.parameters.size() > kMaxMechanismParameters) {
      refuse("mechanisms[" + std::to_string(i) + "] (" + describe(m) + ") has " +
             std::to_string(m.parameters.size()) + " parameters and " +
             std::to_string(m.sigma.size()) + " sigmas; expected as many of each, at most " +
             std::to_string(kMaxMechanismParameters));
    }
  }
  if (model.accuracy) {
    checkAccuracyWritable(*model.accuracy, model.chain_Tracker.dof(), model.mechanisms, refuse);
  }
  const ModelProvenance& p = model.provenance;
  checkString(p.campaign_hash, "provenance.campaign_hash");
  checkString(p.created_utc, "provenance.created_utc");
  checkString(p.trainer_version, "provenance.trainer_version");
  checkString(p.campaign_path, "provenance.campaign_path");
  if (p.validation.size() > kMaxValidationFigures) {
    refuse("provenance has " + std::to_string(p.validation.size()) +
           " validation figures; expected at most " + std::to_string(kMaxValidationFigures));
  }
  for (const ValidationFigure& v : p.validation) checkString(v.method, "validation method");
}

// ---------------------------------------------------------------------------------------------
// Reading

class Reader {
 public:
  Reader(const uint8_t* data, size_t size, const std::string& source)
      : data_(data), limit_(size), source_(source) {}

  [[noreturn]] void fail(size_t offset, const std::string& field,
                         const std::string& problem) const {
    throw InputError("byte " + std::to_string(offset) + ", " + field + ": " + problem, source_);
  }
  size_t offset() const { return pos_; }
  size_t remaining() const { return limit_ - pos_; }

  uint32_t u32(const std::string& field) { return uint32_t(take(4, field)); }
  int32_t i32(const std::string& field) {
    const uint32_t u = u32(field);
    int32_t v = 0;
    std::memcpy(&v, &u, sizeof v);  // two's complement reinterpretation, defined for any bits
    return v;
  }
  uint64_t u64(const std::string& field) { return take(8, field); }

  /// Reads n finite doubles into out; a non-finite one is reported with its index.
  void f64s(double* out, size_t n, const std::string& field) {
    need(8 * n, field);
    for (size_t i = 0; i < n; ++i) {
      const size_t at = pos_;
      out[i] = rawDouble();
      if (!std::isfinite(out[i])) {
        fail(at, n == 1 ? field : field + "[" + std::to_string(i) + "]",
             number(out[i]) + "; expected a finite number");
      }
    }
  }
  double f64(const std::string& field) {
    double v = 0;
    f64s(&v, 1, field);
    return v;
  }
  /// A joint limit: finite, or infinite for a continuous joint, never NaN.
  double limit(const std::string& field) {
    need(8, field);
    const size_t at = pos_;
    const double v = rawDouble();
    if (std::isnan(v)) fail(at, field, "nan; expected a number (±inf for a continuous joint)");
    return v;
  }
  /// A finite double ≥ 0.
  double nonNegative(const std::string& field) {
    const size_t at = pos_;
    const double v = f64(field);
    if (!(v >= 0)) fail(at, field, number(v) + "; expected ≥ 0");
    return v;
  }
  /// A finite double > 0.
  double positive(const std::string& field) {
    const size_t at = pos_;
    const double v = f64(field);
    if (!(v > 0)) fail(at, field, number(v) + "; expected > 0");
    return v;
  }
  /// An m × n matrix stored row by row, every entry finite.
  Eigen::MatrixXd matrix(Eigen::Index rows, Eigen::Index cols, const std::string& field) {
    need(8 * size_t(rows) * size_t(cols), field);
    Eigen::MatrixXd M(rows, cols);
    for (Eigen::Index r = 0; r < rows; ++r) {
      for (Eigen::Index c = 0; c < cols; ++c) {
        const size_t at = pos_;
        M(r, c) = rawDouble();
        if (!std::isfinite(M(r, c))) {
          fail(at, field + "(" + std::to_string(r) + ", " + std::to_string(c) + ")",
               number(M(r, c)) + "; expected a finite number");
        }
      }
    }
    return M;
  }
  Eigen::VectorXd vector(Eigen::Index n, const std::string& field) {
    Eigen::VectorXd v(n);
    f64s(v.data(), size_t(n), field);
    return v;
  }
  /// A vector whose entries are all > 0 (scales).
  Eigen::VectorXd positiveVector(Eigen::Index n, const std::string& field) {
    const size_t at = pos_;
    Eigen::VectorXd v = vector(n, field);
    for (Eigen::Index i = 0; i < n; ++i) {
      if (!(v(i) > 0)) {
        fail(at + 8 * size_t(i), field + "[" + std::to_string(i) + "]",
             number(v(i)) + "; expected > 0 (a scale)");
      }
    }
    return v;
  }

  std::string str(const std::string& field) {
    const size_t at = pos_;
    const uint32_t n = u32(field + " length");
    if (n > kMaxStringBytes) {
      fail(at, field, "length " + std::to_string(n) + "; expected at most " +
                          std::to_string(kMaxStringBytes) + " bytes");
    }
    need(n, field);
    std::string s(reinterpret_cast<const char*>(data_ + pos_), n);
    if (hasControlCharacter(s)) fail(pos_, field, "contains a control character; expected text");
    pos_ += n;
    return s;
  }

  /// A rigid transform: finite, rotation orthonormal with determinant +1.
  Pose pose(const std::string& field) {
    const size_t at = pos_;
    std::array<double, kPoseDoubles> v{};
    f64s(v.data(), v.size(), field);
    Pose X = Pose::Identity();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c) X.matrix()(r, c) = v[size_t(4 * r + c)];
    }
    const Mat3 R = X.linear();
    const double deviation = (R.transpose() * R - Mat3::Identity()).cwiseAbs().maxCoeff();
    if (!(deviation <= kUnitTolerance)) {
      fail(at, field, "rotation is not orthonormal, max |RᵀR − I| = " + number(deviation) +
                          "; expected ≤ " + number(kUnitTolerance) +
                          " (hint: project with lie::projectToSO3 before saving)");
    }
    if (!(R.determinant() > 0)) {
      fail(at, field, "rotation has determinant " + number(R.determinant()) +
                          "; expected +1 (a reflection is not a pose)");
    }
    return X;
  }

  /// A count in [lo, hi] whose items, at least bytes_each each, fit in the section.
  uint32_t count(const std::string& field, uint32_t lo, uint32_t hi, size_t bytes_each) {
    const size_t at = pos_;
    const uint32_t n = u32(field);
    if (n < lo || n > hi) {
      fail(at, field, std::to_string(n) + "; expected " + std::to_string(lo) + " … " +
                          std::to_string(hi));
    }
    if (uint64_t(n) * bytes_each > remaining()) {
      fail(at, field, std::to_string(n) + " items need at least " +
                          std::to_string(uint64_t(n) * bytes_each) + " bytes, the section has " +
                          std::to_string(remaining()) + " left; expected a consistent count");
    }
    return n;
  }

  /// Reads the next section header, which must be `id`, and confines reads to its payload.
  void enterSection(const SectionId& id, size_t file_limit) {
    section_ = std::string("section ") + tagText(id.tag) + " (" + id.name + ")";
    const std::string& what = section_;
    limit_ = file_limit;
    const size_t at = pos_;
    const uint32_t tag = u32(what + " tag");
    if (tag != id.tag) {
      fail(at, what, "found tag " + tagText(tag) +
                         "; expected the sections CHAN, NOMI, REGI, COMP, MECH, GPR, PROV "
                         "(then ACCU, optional) in that order");
    }
    const uint32_t reserved = u32(what + " reserved word");
    if (reserved != 0) {
      fail(at + 4, what, "reserved word is " + hex32(reserved) + "; expected 0");
    }
    const uint64_t length = u64(what + " length");
    if (length > remaining()) {
      fail(at + 8, what, "length " + std::to_string(length) + " bytes, only " +
                             std::to_string(remaining()) +
                             " remain before the checksum; expected a length that fits");
    }
    section_end_ = pos_ + size_t(length);
    limit_ = section_end_;
  }
  /// Checks the payload was consumed exactly.
  void leaveSection() {
    if (pos_ != section_end_) {
      fail(pos_, section_, std::to_string(section_end_ - pos_) +
                               " bytes left over in the payload; expected none");
    }
  }

 private:
  void need(size_t bytes, const std::string& field) const {
    if (bytes > remaining()) {
      fail(pos_, field, "needs " + std::to_string(bytes) + " bytes, only " +
                            std::to_string(remaining()) + " remain in " +
                            (section_.empty() ? std::string("the file") : section_) +
                            "; expected a complete value");
    }
  }
  uint64_t take(int bytes, const std::string& field) {
    need(size_t(bytes), field);
    uint64_t v = 0;
    for (int i = 0; i < bytes; ++i) v |= uint64_t(data_[pos_ + size_t(i)]) << (8 * i);
    pos_ += size_t(bytes);
    return v;
  }
  double rawDouble() {
    const uint64_t bits = take(8, "double");
    double v = 0;
    std::memcpy(&v, &bits, sizeof v);
    return v;
  }

  const uint8_t* data_;
  size_t pos_ = 0;
  size_t limit_;
  size_t section_end_ = 0;
  std::string section_;
  const std::string& source_;
};

/// A chain as CHAN stores it; field names start with prefix ("chain.dof"). When `like` is
/// given, the chain must have like's dof and joint names.
KinematicChain readChain(Reader& in, const std::string& prefix, const KinematicChain* like) {
  const size_t dof_at = in.offset();
  const uint32_t n = in.count(prefix + ".dof", 1, kMaxJoints, 4 + 8 * 8);
  if (like != nullptr && n != uint32_t(like->dof())) {
    in.fail(dof_at, prefix + ".dof",
            std::to_string(n) + "; expected " + std::to_string(like->dof()) +
                ", the calibrated chain's (both describe the same robot)");
  }
  std::vector<ChainJoint> joints(n);
  for (uint32_t i = 0; i < n; ++i) {
    const std::string field = prefix + ".joints[" + std::to_string(i) + "]";
    ChainJoint& j = joints[i];
    const size_t name_at = in.offset();
    j.name = in.str(field + ".name");
    if (like != nullptr && j.name != like->joints()[i].name) {
      in.fail(name_at, field + ".name",
              "'" + j.name + "'; expected '" + like->joints()[i].name +
                  "', the calibrated chain's joint " + std::to_string(i + 1));
    }
    const size_t twist_at = in.offset();
    in.f64s(j.twist_Local.data(), 6, field + ".twist_Local");
    const double axis_norm = j.twist_Local.tail<3>().norm();
    if (!(std::abs(axis_norm - 1) <= kUnitTolerance)) {
      in.fail(twist_at + 24, field + ".twist_Local",
              "rotation axis has norm " + number(axis_norm) + "; expected 1 within " +
                  number(kUnitTolerance) + " (a revolute joint)");
    }
    const size_t limits_at = in.offset();
    j.lower_rad = in.limit(field + ".lower_rad");
    j.upper_rad = in.limit(field + ".upper_rad");
    if (!(j.lower_rad <= j.upper_rad) || j.lower_rad == kInfinity || j.upper_rad == -kInfinity) {
      in.fail(limits_at, field, "limits " + number(j.lower_rad) + " … " + number(j.upper_rad) +
                                    " rad; expected lower ≤ upper (−inf … inf for a "
                                    "continuous joint)");
    }
  }
  std::vector<Pose> initial;
  initial.reserve(n + 1);
  for (uint32_t k = 0; k <= n; ++k) {
    initial.push_back(in.pose(prefix + ".initial_poses[" + std::to_string(k) + "]"));
  }
  const uint32_t f = in.count(prefix + ".frame_count", 0, kMaxFrames, 4 + 4 + 8 * kPoseDoubles);
  std::vector<AttachedFrame> frames(f);
  for (uint32_t i = 0; i < f; ++i) {
    const std::string field = prefix + ".frames[" + std::to_string(i) + "]";
    frames[i].name = in.str(field + ".name");
    const size_t parent_at = in.offset();
    const uint32_t parent = in.u32(field + ".parent");
    if (parent > n) {
      in.fail(parent_at, field + ".parent",
              std::to_string(parent) + "; expected 0 … " + std::to_string(n) +
                  " (root or a joint of this " + std::to_string(n) + "-joint chain)");
    }
    frames[i].parent = int(parent);
    frames[i].X_ParentFrame = in.pose(field + ".X_ParentFrame");
  }
  return KinematicChain(std::move(joints), std::move(initial), std::move(frames));
}

void readRegistration(Reader& in, CalibratedModel& model) {
  model.X_TrackerBase = in.pose("registration.X_TrackerBase");
  in.f64s(model.gravity_Base.data(), 3, "registration.gravity_Base");
  const size_t at = in.offset();
  model.sensor_frame = in.i32("registration.sensor_frame");
  const int frames = int(model.chain_Tracker.frames().size());
  if (model.sensor_frame < -1 || model.sensor_frame >= frames) {
    in.fail(at, "registration.sensor_frame",
            std::to_string(model.sensor_frame) + "; expected −1 (no sensor) or 0 … " +
                std::to_string(frames - 1) + " (the chain has " + std::to_string(frames) +
                " attached frames)");
  }
}

void readCompliance(Reader& in, CalibratedModel& model) {
  const size_t at = in.offset();
  const uint32_t c = in.u32("compliance.count");
  const int n = model.chain_Tracker.dof();
  if (c != 0 && c != uint32_t(n)) {
    in.fail(at, "compliance.count",
            std::to_string(c) + "; expected 0 (no compliance step) or the dof, " +
                std::to_string(n));
  }
  model.compliance_rad_per_nm.resize(c);
  model.compliance_sigma_rad_per_nm.resize(c);
  for (uint32_t i = 0; i < c; ++i) {
    model.compliance_rad_per_nm(i) =
        in.nonNegative("compliance.compliance_rad_per_nm[" + std::to_string(i) + "]");
  }
  for (uint32_t i = 0; i < c; ++i) {
    model.compliance_sigma_rad_per_nm(i) =
        in.nonNegative("compliance.compliance_sigma_rad_per_nm[" + std::to_string(i) + "]");
  }
}

/// The MECH section: each record checked as it is read, so an error names its offset.
void readMechanisms(Reader& in, CalibratedModel& model) {
  const uint32_t k = in.count("mechanisms.count", 0, kMaxMechanisms, kMechanismHeaderBytes);
  model.mechanisms.reserve(k);
  for (uint32_t i = 0; i < k; ++i) {
    const std::string field = "mechanisms[" + std::to_string(i) + "]";
    const size_t at = in.offset();
    Mechanism m;
    m.kind = static_cast<MechanismKind>(in.u32(field + ".kind"));
    m.joint = in.i32(field + ".joint");
    m.source_joint = in.i32(field + ".source_joint");
    m.order = in.i32(field + ".order");
    const uint32_t p =
        in.count(field + ".parameter_count", 0, kMaxMechanismParameters, 2 * sizeof(double));
    m.parameters.resize(p);
    m.sigma.resize(p);
    in.f64s(m.parameters.data(), p, field + ".parameters");
    in.f64s(m.sigma.data(), p, field + ".sigma");
    const uint32_t arcs = in.count(field + ".coverage.arc_count", 0, kMaxCoverageArcs,
                                   2 * sizeof(double));
    m.coverage.arcs_rad.resize(2 * size_t(arcs));
    in.f64s(m.coverage.arcs_rad.data(), m.coverage.arcs_rad.size(), field + ".coverage.arcs_rad");
    in.f64s(&m.coverage.fade_rad, 1, field + ".coverage.fade_rad");
    model.mechanisms.push_back(std::move(m));
    const std::string problem = mechanismInModelProblem(model, i);
    if (!problem.empty()) in.fail(at, field, problem);
  }
}

/// Normwise backward error of α as a solution of (K + σ_n² I) α = Y, Frobenius norms, with
/// K_ij = σ_f² exp(−½ Σ_d ((x_id − x_jd) / ℓ_d)²) (eq. 27, 30). Row by row, so memory stays
/// O(m) however large m is. NaN when the hyperparameters overflow.
double alphaBackwardError(const GprParameters& g) {
  const Eigen::Index m = g.inputs_normalised.rows();
  // Columns are samples, so each inner loop walks contiguous memory.
  const Eigen::MatrixXd Z =
      (g.inputs_normalised.array().rowwise() / g.length_scales.transpose().array()).transpose();
  const Eigen::MatrixXd alpha_t = g.alpha.transpose();
  const double sf2 = g.signal_sigma * g.signal_sigma;
  const double sn2 = g.noise_sigma * g.noise_sigma;
  Eigen::VectorXd r(g.alpha.cols());
  double residual_squares = 0, matrix_squares = 0;
  for (Eigen::Index i = 0; i < m; ++i) {
    r = -g.targets_standardised.row(i).transpose();
    for (Eigen::Index j = 0; j < m; ++j) {
      const double a = sf2 * std::exp(-0.5 * (Z.col(i) - Z.col(j)).squaredNorm()) +
                       (i == j ? sn2 : 0.0);
      r += a * alpha_t.col(j);
      matrix_squares += a * a;
    }
    residual_squares += r.squaredNorm();
  }
  const double residual = std::sqrt(residual_squares);
  if (residual == 0) return 0;  // exact, also when α = Y = 0
  return residual / (std::sqrt(matrix_squares) * g.alpha.norm() + g.targets_standardised.norm());
}

void readGpr(Reader& in, CalibratedModel& model, size_t payload_bytes) {
  const size_t at = in.offset();
  const uint32_t m = in.u32("gpr.m");
  const uint32_t D = in.u32("gpr.D");
  const uint32_t P = in.u32("gpr.P");
  if (m == 0 && D == 0 && P == 0) return;  // no residual step
  if (m < 1 || m > kMaxGprSamples || D < 1 || D > kMaxGprDims || P < 1 || P > kMaxGprDims) {
    in.fail(at, "gpr.m/D/P",
            std::to_string(m) + " samples, " + std::to_string(D) + " inputs, " +
                std::to_string(P) + " outputs; expected all 0 (no residual step) or 1 … " +
                std::to_string(kMaxGprSamples) + " samples and 1 … " +
                std::to_string(kMaxGprDims) + " inputs and outputs");
  }
  // The sizes fix the payload length (a GPR per payload force: 8 more bytes, its reference
  // force, after α); checking it first bounds every allocation below.
  const uint64_t expected = gprPayloadBytes(m, D, P);
  const bool per_payload_force = payload_bytes == expected + kPayloadForceBytes && D >= 6;
  if (expected != payload_bytes && !per_payload_force) {
    in.fail(at, "gpr", "payload has " + std::to_string(payload_bytes) + " bytes; expected " +
                           std::to_string(expected) + " for m = " + std::to_string(m) +
                           ", D = " + std::to_string(D) + ", P = " + std::to_string(P) +
                           " (or " + std::to_string(expected + kPayloadForceBytes) +
                           " for a GPR per payload force, D ≥ 6)");
  }
  GprParameters g;
  g.input_offset = in.vector(D, "gpr.input_offset");
  g.input_scale = in.positiveVector(D, "gpr.input_scale");
  g.output_mean = in.vector(P, "gpr.output_mean");
  g.output_scale = in.positiveVector(P, "gpr.output_scale");
  g.length_scales = in.positiveVector(D, "gpr.length_scales");
  g.signal_sigma = in.positive("gpr.signal_sigma");
  g.noise_sigma = in.positive("gpr.noise_sigma");
  g.inputs_normalised = in.matrix(m, D, "gpr.inputs_normalised");
  g.targets_standardised = in.matrix(m, P, "gpr.targets_standardised");
  const size_t alpha_at = in.offset();
  g.alpha = in.matrix(m, P, "gpr.alpha");
  if (per_payload_force) g.payload_force_reference_n = in.positive("gpr.payload_force_reference_n");
  const double backward_error = alphaBackwardError(g);
  // "Not ≤", so that NaN from overflowing hyperparameters is refused too.
  if (!(backward_error <= kAlphaBackwardErrorLimit)) {
    in.fail(alpha_at, "gpr.alpha",
            "does not solve (K + σ_n² I) α = Y, backward error ‖(K + σ_n² I) α − Y‖ / "
            "(‖K + σ_n² I‖ ‖α‖ + ‖Y‖) = " +
                number(backward_error) + "; expected ≤ " + number(kAlphaBackwardErrorLimit) +
                ": the file is inconsistent (hint: retrain; the GPR arrays or hyperparameters "
                "were altered after training)");
  }
  model.gpr = std::move(g);
}

void readProvenance(Reader& in, ModelProvenance& p) {
  const size_t hash_at = in.offset();
  p.campaign_hash = in.str("provenance.campaign_hash");
  if (!isHex(p.campaign_hash)) {
    in.fail(hash_at, "provenance.campaign_hash",
            "'" + p.campaign_hash + "'; expected hexadecimal digits");
  }
  p.created_utc = in.str("provenance.created_utc");
  p.trainer_version = in.str("provenance.trainer_version");
  p.campaign_path = in.str("provenance.campaign_path");
  const uint32_t v =
      in.count("provenance.validation_count", 0, kMaxValidationFigures, 4 + 4 + 8 * 4);
  p.validation.resize(v);
  for (uint32_t i = 0; i < v; ++i) {
    const std::string field = "provenance.validation[" + std::to_string(i) + "]";
    ValidationFigure& f = p.validation[i];
    f.method = in.str(field + ".method");
    f.load_kg = in.nonNegative(field + ".load_kg");
    const size_t rows_at = in.offset();
    f.rows = in.i32(field + ".rows");
    if (f.rows < 0) {
      in.fail(rows_at, field + ".rows", std::to_string(f.rows) + "; expected ≥ 0");
    }
    f.mean_position_m = in.nonNegative(field + ".mean_position_m");
    f.max_position_m = in.nonNegative(field + ".max_position_m");
    f.mean_orientation_rad = in.nonNegative(field + ".mean_orientation_rad");
  }
}

/// The ACCU section: the factors of the parameters' covariance and the measurement noise.
AccuracyFactors readAccuracy(Reader& in, int n, const std::vector<Mechanism>& mechanisms) {
  const size_t version_at = in.offset();
  const uint32_t version = in.u32("accuracy.layout_version");
  if (version != AccuracyFactors::kLayoutVersion) {
    in.fail(version_at, "accuracy.layout_version",
            std::to_string(version) + "; expected " +
                std::to_string(AccuracyFactors::kLayoutVersion) +
                " (hint: re-run `stepcal calibrate` with this build)");
  }
  AccuracyFactors a;
  a.position_noise_m = in.nonNegative("accuracy.position_noise_m");
  a.orientation_noise_rad = in.nonNegative("accuracy.orientation_noise_rad");
  const uint32_t geometry_rows = uint32_t(6 * (n + 1));
  const size_t g_at = in.offset();
  const uint32_t g = in.u32("accuracy.geometry_rows");
  if (g != 0 && g != geometry_rows) {
    in.fail(g_at, "accuracy.geometry_rows",
            std::to_string(g) + "; expected 0 or 6(n+1) = " + std::to_string(geometry_rows));
  }
  const uint32_t r = in.count("accuracy.geometry_rank", 0, g, 8 * size_t(g));
  a.geometry_factor = in.matrix(g, r, "accuracy.geometry_factor");
  const size_t c_at = in.offset();
  const uint32_t c = in.u32("accuracy.compliance_count");
  if (c != 0 && c != uint32_t(n)) {
    in.fail(c_at, "accuracy.compliance_count",
            std::to_string(c) + "; expected 0 or the dof, " + std::to_string(n));
  }
  a.compliance_factor = in.matrix(c, c, "accuracy.compliance_factor");
  const uint32_t k = in.count("accuracy.profile_count", 0, uint32_t(mechanisms.size()), 8);
  for (uint32_t i = 0; i < k; ++i) {
    const std::string field = "accuracy.profile_factors[" + std::to_string(i) + "]";
    ProfileCovarianceFactor p;
    const size_t m_at = in.offset();
    p.mechanism = in.u32(field + ".mechanism");
    if (p.mechanism >= mechanisms.size() ||
        mechanisms[p.mechanism].kind != MechanismKind::kTransmissionError ||
        (i > 0 && p.mechanism <= a.profile_factors.back().mechanism)) {
      in.fail(m_at, field + ".mechanism",
              std::to_string(p.mechanism) +
                  "; expected the index of a transmission_error in MECH, ascending");
    }
    const uint32_t rows = uint32_t(2 * mechanisms[p.mechanism].order);
    const uint32_t r = in.count(field + ".rank", 0, rows, 8 * size_t(rows));
    p.factor = in.matrix(rows, r, field + ".factor");
    a.profile_factors.push_back(std::move(p));
  }
  return a;
}

CalibratedModel parseChecked(const uint8_t* data, size_t size, const std::string& source) {
  Reader in(data, size, source);
  if (size < kMagic.size() || std::memcmp(data, kMagic.data(), kMagic.size()) != 0) {
    in.fail(0, "magic", "not a stepcal model file; expected it to start with \"STEPCAL\\0\"");
  }
  if (size < kHeaderBytes + kCrcBytes) {
    in.fail(size, "header", "file ends after " + std::to_string(size) +
                                " bytes; expected at least " +
                                std::to_string(kHeaderBytes + kCrcBytes) + " (truncated)");
  }
  in.u64("magic");
  const uint32_t version = in.u32("version");
  if (version != kModelFormatVersion) {
    in.fail(8, "version",
            "model format version " + std::to_string(version) + ", this build reads " +
                std::to_string(kModelFormatVersion) +
                " (no reader of other versions); hint: re-run `stepcal calibrate` (and "
                "`stepcal diagnose --out` for an extended model) on the campaign to write the "
                "model in this format");
  }
  const uint32_t flags = in.u32("flags");
  if (flags != 0) {
    in.fail(12, "flags", hex32(flags) + "; expected 0 (this build knows no flags)");
  }
  const uint64_t declared = in.u64("file size");
  if (declared != size) {
    in.fail(16, "file size",
            "header says " + std::to_string(declared) + " bytes, there are " +
                std::to_string(size) + "; expected equal (the file is truncated or extended)");
  }
  const size_t crc_at = size - kCrcBytes;
  uint32_t stored_crc = 0;
  for (size_t i = 0; i < kCrcBytes; ++i) stored_crc |= uint32_t(data[crc_at + i]) << (8 * i);
  const uint32_t actual_crc = crc32Ieee(data, crc_at);
  if (stored_crc != actual_crc) {
    in.fail(crc_at, "checksum",
            "stored CRC-32 " + hex32(stored_crc) + ", the content gives " + hex32(actual_crc) +
                "; the file is corrupted (hint: copy it again from the trainer's output)");
  }

  CalibratedModel model;
  in.enterSection(kChain, crc_at);
  model.chain_Tracker = readChain(in, "chain", nullptr);
  in.leaveSection();
  in.enterSection(kNominal, crc_at);
  model.nominal_Base = readChain(in, "nominal", &model.chain_Tracker);
  in.leaveSection();
  in.enterSection(kRegistration, crc_at);
  readRegistration(in, model);
  in.leaveSection();
  in.enterSection(kCompliance, crc_at);
  readCompliance(in, model);
  in.leaveSection();
  in.enterSection(kMechanisms, crc_at);
  readMechanisms(in, model);
  in.leaveSection();
  in.enterSection(kGpr, crc_at);
  readGpr(in, model, in.remaining());
  in.leaveSection();
  in.enterSection(kProvenance, crc_at);
  readProvenance(in, model.provenance);
  in.leaveSection();
  if (in.offset() != crc_at) {
    in.enterSection(kAccuracy, crc_at);
    model.accuracy = readAccuracy(in, model.chain_Tracker.dof(), model.mechanisms);
    in.leaveSection();
  }
  if (in.offset() != crc_at) {
    in.fail(in.offset(), "end of sections",
            std::to_string(crc_at - in.offset()) +
                " bytes follow the last section; expected the checksum");
  }
  return model;
}

std::string systemMessage(int error) { return std::system_category().message(error); }

}  // namespace

uint32_t crc32Ieee(const uint8_t* data, size_t size) noexcept {
  const auto word = [](const uint8_t* p) {
    return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24;
  };
  uint32_t c = 0xFFFFFFFFu;
  size_t i = 0;
  for (; i + 8 <= size; i += 8) {
    const uint32_t lo = c ^ word(data + i);
    const uint32_t hi = word(data + i + 4);
    c = kCrc[7][lo & 0xFFu] ^ kCrc[6][(lo >> 8) & 0xFFu] ^ kCrc[5][(lo >> 16) & 0xFFu] ^
        kCrc[4][lo >> 24] ^ kCrc[3][hi & 0xFFu] ^ kCrc[2][(hi >> 8) & 0xFFu] ^
        kCrc[1][(hi >> 16) & 0xFFu] ^ kCrc[0][hi >> 24];
  }
  for (; i < size; ++i) c = kCrc[0][(c ^ data[i]) & 0xFFu] ^ (c >> 8);
  return c ^ 0xFFFFFFFFu;
}

std::vector<uint8_t> serializeModel(const CalibratedModel& model) {
  const std::string source = "model being serialised";
  checkWritable(model, source);
  Writer out;
  for (const uint8_t b : kMagic) out.bytes().push_back(b);
  out.u32(kModelFormatVersion);
  out.u32(0);
  out.u64(0);  // file size, patched below

  size_t at = out.beginSection(kChain);
  out.chainPayload(model.chain_Tracker);
  out.endSection(at);

  at = out.beginSection(kNominal);
  out.chainPayload(model.nominal_Base);
  out.endSection(at);

  at = out.beginSection(kRegistration);
  out.pose(model.X_TrackerBase);
  for (int i = 0; i < 3; ++i) out.f64(model.gravity_Base(i));
  out.i32(model.sensor_frame);
  out.endSection(at);

  at = out.beginSection(kCompliance);
  out.u32(uint32_t(model.compliance_rad_per_nm.size()));
  out.rowMajor(model.compliance_rad_per_nm);
  out.rowMajor(model.compliance_sigma_rad_per_nm);
  out.endSection(at);

  at = out.beginSection(kMechanisms);
  out.u32(uint32_t(model.mechanisms.size()));
  for (const Mechanism& m : model.mechanisms) {
    out.u32(static_cast<uint32_t>(m.kind));
    out.i32(m.joint);
    out.i32(m.source_joint);
    out.i32(m.order);
    out.u32(uint32_t(m.parameters.size()));
    for (const double v : m.parameters) out.f64(v);
    for (const double v : m.sigma) out.f64(v);
    out.u32(uint32_t(m.coverage.arcs_rad.size() / 2));
    for (const double v : m.coverage.arcs_rad) out.f64(v);
    out.f64(m.coverage.fade_rad);
  }
  out.endSection(at);

  at = out.beginSection(kGpr);
  if (model.gpr) {
    const GprParameters& g = *model.gpr;
    out.u32(uint32_t(g.inputs_normalised.rows()));
    out.u32(uint32_t(g.inputs_normalised.cols()));
    out.u32(uint32_t(g.alpha.cols()));
    out.rowMajor(g.input_offset);
    out.rowMajor(g.input_scale);
    out.rowMajor(g.output_mean);
    out.rowMajor(g.output_scale);
    out.rowMajor(g.length_scales);
    out.f64(g.signal_sigma);
    out.f64(g.noise_sigma);
    out.rowMajor(g.inputs_normalised);
    out.rowMajor(g.targets_standardised);
    out.rowMajor(g.alpha);
    // Only a GPR per payload force writes its reference: the paper's is written as before.
    if (g.payload_force_reference_n > 0.0) out.f64(g.payload_force_reference_n);
  } else {
    for (int i = 0; i < 3; ++i) out.u32(0);
  }
  out.endSection(at);

  const ModelProvenance& p = model.provenance;
  at = out.beginSection(kProvenance);
  out.str(p.campaign_hash);
  out.str(p.created_utc);
  out.str(p.trainer_version);
  out.str(p.campaign_path);
  out.u32(uint32_t(p.validation.size()));
  for (const ValidationFigure& v : p.validation) {
    out.str(v.method);
    out.f64(v.load_kg);
    out.i32(v.rows);
    out.f64(v.mean_position_m);
    out.f64(v.max_position_m);
    out.f64(v.mean_orientation_rad);
  }
  out.endSection(at);

  // Only a model with a bound writes ACCU: one without is written as before.
  if (model.accuracy) {
    const AccuracyFactors& a = *model.accuracy;
    at = out.beginSection(kAccuracy);
    out.u32(AccuracyFactors::kLayoutVersion);
    out.f64(a.position_noise_m);
    out.f64(a.orientation_noise_rad);
    out.u32(uint32_t(a.geometry_factor.rows()));
    out.u32(uint32_t(a.geometry_factor.cols()));
    out.rowMajor(a.geometry_factor);
    out.u32(uint32_t(a.compliance_factor.rows()));
    out.rowMajor(a.compliance_factor);
    out.u32(uint32_t(a.profile_factors.size()));
    for (const ProfileCovarianceFactor& p : a.profile_factors) {
      out.u32(p.mechanism);
      out.u32(uint32_t(p.factor.cols()));
      out.rowMajor(p.factor);
    }
    out.endSection(at);
  }

  std::vector<uint8_t>& bytes = out.bytes();
  const uint64_t total = bytes.size() + kCrcBytes;
  for (int i = 0; i < 8; ++i) bytes[16 + size_t(i)] = uint8_t(total >> (8 * i));
  out.u32(crc32Ieee(bytes.data(), bytes.size()));
  // The loader's checks are the definition of a valid model; run them on what was written.
  parseModel(bytes.data(), bytes.size(), source);
  return std::move(bytes);
}

CalibratedModel parseModel(const uint8_t* data, size_t size, const std::string& source) {
  try {
    return parseChecked(data, size, source);
  } catch (const std::bad_alloc&) {
    throw InputError("not enough memory to load the model (" + std::to_string(size) + " bytes)",
                     source);
  }
}

void writeModelFile(const CalibratedModel& model, const std::string& path) {
  const std::vector<uint8_t> bytes = serializeModel(model);
  writeFileAtomically(path, bytes.data(), bytes.size(), "model");
}

CalibratedModel readModelFile(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY);
  if (fd < 0) throw InputError("cannot open the model file (" + systemMessage(errno) + ")", path);
  std::vector<uint8_t> bytes;
  int error = 0;
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    error = errno;
  } else if (S_ISDIR(st.st_mode)) {
    ::close(fd);
    throw InputError("is a folder; expected a stepcal model file (what `stepcal calibrate --out` "
                     "writes)",
                     path);
  } else if (!S_ISREG(st.st_mode) || uint64_t(st.st_size) > kMaxFileBytes) {
    ::close(fd);
    throw InputError("not a regular file of at most " + std::to_string(kMaxFileBytes) +
                         " bytes; expected a stepcal model file",
                     path);
  } else {
    bytes.resize(size_t(st.st_size));
    size_t done = 0;
    while (done < bytes.size()) {
      const ssize_t n = ::read(fd, bytes.data() + done, bytes.size() - done);
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) {
        error = errno;
        break;
      }
      if (n == 0) break;  // shrank while reading; the size check in parseModel reports it
      done += size_t(n);
    }
    bytes.resize(done);
  }
  ::close(fd);
  if (error != 0) throw InputError("cannot read the model file (" + systemMessage(error) + ")", path);
  return parseModel(bytes.data(), bytes.size(), path);
}

}  // namespace stepcal

namespace stepcal {

std::string mechanismInModelProblem(const CalibratedModel& model, size_t index) {
  const Mechanism& m = model.mechanisms[index];
  const std::string problem = mechanismProblem(m, model.chain_Tracker.dof());
  if (!problem.empty()) return problem;
  if (isMeasurementOnly(m.kind)) {
    return std::string(toString(m.kind)) +
           " describes a campaign's measurement (its tracker, its tool, its readings), not the "
           "robot as it is now; expected none in a model file (hint: the diagnosis leaves it out of the model it writes)";
  }
  // How many of its kind a model holds (MechanismTraits): e.g. one self weight, and per joint
  // one profile, one profile geometry, one torsion curve.
  const MechanismTraits::Multiplicity multiplicity = findMechanismTraits(m.kind)->multiplicity;
  const bool single = multiplicity == MechanismTraits::Multiplicity::kOnePerModel;
  const bool per_joint = multiplicity == MechanismTraits::Multiplicity::kOnePerJoint;
  for (size_t i = 0; i < index; ++i) {
    const Mechanism& earlier = model.mechanisms[i];
    if (earlier.kind != m.kind) continue;
    if (single) {
      return std::string("a second ") + toString(m.kind) + " (the first is mechanisms[" +
             std::to_string(i) + "]); expected at most one";
    }
    if (per_joint && earlier.joint == m.joint) {
      return std::string("a second ") + toString(m.kind) + " of joint " +
             std::to_string(m.joint + 1) + " (the first is mechanisms[" + std::to_string(i) +
             "]); expected at most one per joint";
    }
  }
  const auto profiled = [&](int joint) {
    for (const Mechanism& other : model.mechanisms) {
      if (other.kind == MechanismKind::kTransmissionError && other.joint == joint) return true;
    }
    return false;
  };
  if (m.kind == MechanismKind::kProfileGeometry && !profiled(m.joint)) {
    return "profile_geometry of joint " + std::to_string(m.joint + 1) +
           " without a transmission_error of that joint; expected the profile it goes with";
  }
  if (m.kind == MechanismKind::kSensorBias && model.sensor_frame < 0) {
    return "sensor_bias in a model without a sensor frame (registration.sensor_frame = " +
           std::to_string(model.sensor_frame) + "); expected a sensor frame to bias";
  }
  if (m.kind == MechanismKind::kSelfWeight && model.gravity_Base.isZero(0.0)) {
    return "self_weight in a model whose gravity is zero (registration.gravity_Base); expected "
           "a nonzero gravity to weigh the links";
  }
  return {};
}

PhysicalModel physicalModelOf(const CalibratedModel& model) {
  PhysicalModel physical;
  physical.chain_Tracker = model.chain_Tracker;
  physical.sensor_frame = model.sensor_frame;
  const int n = model.chain_Tracker.dof();
  physical.compliance_rad_per_nm = model.compliance_rad_per_nm.size() == n
                                       ? model.compliance_rad_per_nm
                                       : JointVector(JointVector::Zero(n));
  physical.gravity_Tracker = model.X_TrackerBase.linear() * model.gravity_Base;
  physical.mechanisms = model.mechanisms;
  return physical;
}

}  // namespace stepcal
