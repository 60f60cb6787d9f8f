// The language-independent half of the filters: which language a file is in, the conversion of
// a literal's numbers to SI and back (each orientation written nearest the one it replaces, so
// that C −180 stays −180 and a quaternion keeps its sign), and the writer that replaces only the
// numbers of the targets given.
#include "stepcal/programs/program.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "scan.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/units.hpp"

namespace stepcal::programs {
namespace detail {
Program readKrl(std::string_view text, const std::string& path);
Program readRapid(std::string_view text, const std::string& path);
Program readUrScript(std::string_view text, const std::string& path);
Program readFanucTp(std::string_view text, const std::string& path);
}  // namespace detail

namespace {

using detail::lowerCase;

constexpr double kUnchangedPosition_m = 1e-7;
constexpr double kUnchangedAngle_rad = 1e-7;

/// Digits after the point a rewritten number gets at the least: 1 µm, 1e-4 deg, 1e-8 of a
/// quaternion, 1e-6 rad.
int minimumDecimals(const Program& program, bool position, bool joint) {
  if (joint) return program.file_units_per_rad > 1.0 ? 4 : 6;
  if (position) return program.file_units_per_m > 1.0 ? 3 : 6;
  switch (program.orientation) {
    case Orientation::kQuaternionWxyz: return 8;
    case Orientation::kRotationVector: return 6;
    default: return 4;
  }
}

/// The angle (deg) equal to `angle_deg` modulo 360 nearest `near_deg`, kept within ±180 unless
/// the one it replaces was beyond.
double nearestTurn(double angle_deg, double near_deg) {
  double a = angle_deg + 360.0 * std::round((near_deg - angle_deg) / 360.0);
  if (std::abs(near_deg) <= 180.0) {
    if (a > 180.0) a -= 360.0;
    if (a < -180.0) a += 360.0;
  }
  return a;
}

/// Z, Y′, X″ angles (deg) of R, of its two solutions the nearer to the angles written before.
Vec3 zyxNearest(const Mat3& R, const Vec3& written_deg) {
  const double b = std::asin(std::clamp(-R(2, 0), -1.0, 1.0));
  const double a = std::atan2(R(1, 0), R(0, 0)), c = std::atan2(R(2, 1), R(2, 2));
  const Vec3 first = Vec3(a, b, c) / kRadPerDeg;
  const Vec3 second(first[0] + 180.0, 180.0 - first[1], first[2] + 180.0);
  Vec3 best = first;
  double best_distance = INFINITY;
  for (const Vec3& candidate : {first, second}) {
    Vec3 wrapped;
    for (int k = 0; k < 3; ++k) wrapped[k] = nearestTurn(candidate[k], written_deg[k]);
    const double distance = (wrapped - written_deg).cwiseAbs().sum();
    if (distance < best_distance) {
      best_distance = distance;
      best = wrapped;
    }
  }
  return best;
}

/// The rotation vector of R nearest the one written before (θ and θ − 2π about the axis, or −axis
/// at θ = π, are the same rotation).
Vec3 rotationVectorNearest(const Mat3& R, const Vec3& written) {
  const Eigen::AngleAxisd aa(R);
  const Vec3 v = aa.axis() * aa.angle();
  Vec3 best = v;
  for (const Vec3& candidate : {v, Vec3(-v), Vec3(aa.axis() * (aa.angle() - 2.0 * kPi))}) {
    if ((candidate - written).norm() < (best - written).norm() &&
        lie::angleBetween(Eigen::AngleAxisd(candidate.norm(), candidate.normalized()).toRotationMatrix(), R) < 1e-9) {
      best = candidate;
    }
  }
  return best;
}

/// A target's new numbers in the file's units and convention.
std::vector<double> newValues(const Program& program, const Target& target, const Replacement& r) {
  if (target.kind == TargetKind::kJoint) {
    std::vector<double> out;
    for (int j = 0; j < r.q_rad.size(); ++j) out.push_back(r.q_rad[j] * program.file_units_per_rad);
    return out;
  }
  const Vec3 p = r.X_FrameTcp.translation() * program.file_units_per_m;
  std::vector<double> out = {p.x(), p.y(), p.z()};
  const Mat3 R = r.X_FrameTcp.linear();
  const std::vector<double>& w = target.written;
  switch (program.orientation) {
    case Orientation::kZyxDeg: {
      const Vec3 abc = zyxNearest(R, Vec3(w[3], w[4], w[5]));
      out.insert(out.end(), {abc[0], abc[1], abc[2]});
      break;
    }
    case Orientation::kFixedXyzDeg: {
      const Vec3 rpw = zyxNearest(R, Vec3(w[5], w[4], w[3]));
      out.insert(out.end(), {rpw[2], rpw[1], rpw[0]});
      break;
    }
    case Orientation::kQuaternionWxyz: {
      Eigen::Quaterniond q(R);
      if (q.w() * w[3] + q.x() * w[4] + q.y() * w[5] + q.z() * w[6] < 0.0) q.coeffs() *= -1.0;
      out.insert(out.end(), {q.w(), q.x(), q.y(), q.z()});
      break;
    }
    case Orientation::kRotationVector: {
      const Vec3 v = rotationVectorNearest(R, Vec3(w[3], w[4], w[5]));
      out.insert(out.end(), {v[0], v[1], v[2]});
      break;
    }
  }
  return out;
}

std::string formatFixed(double value, int decimals) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%.*f", decimals, value);
  std::string text(buffer);
  // "-0.000" reads as a sign where there is none.
  if (text[0] == '-' && text.find_first_not_of("-0.") == std::string::npos) text.erase(0, 1);
  return text;
}

}  // namespace

std::optional<Language> languageOf(const std::string& path, const std::string& format) {
  const std::string f = lowerCase(format);
  if (f == "krl") return Language::kKrl;
  if (f == "rapid") return Language::kRapid;
  if (f == "urscript") return Language::kUrScript;
  if (f == "tp") return Language::kFanucTp;
  if (f == "csv") return std::nullopt;
  if (!f.empty()) {
    throw InputError("--format '" + format + "': expected csv, krl, rapid, urscript or tp");
  }
  const std::string ext = lowerCase(std::filesystem::path(path).extension().string());
  if (ext == ".src" || ext == ".dat") return Language::kKrl;
  if (ext == ".mod" || ext == ".prg" || ext == ".sys") return Language::kRapid;
  if (ext == ".script") return Language::kUrScript;
  if (ext == ".ls") return Language::kFanucTp;
  return std::nullopt;
}

std::string languageName(Language language) {
  switch (language) {
    case Language::kKrl: return "KUKA KRL";
    case Language::kRapid: return "ABB RAPID";
    case Language::kUrScript: return "URScript";
    case Language::kFanucTp: return "Fanuc TP";
  }
  return "";
}

Program readProgram(Language language, std::string_view text, const std::string& path) {
  detail::requireText(text, path);
  switch (language) {
    case Language::kKrl: return detail::readKrl(text, path);
    case Language::kRapid: return detail::readRapid(text, path);
    case Language::kUrScript: return detail::readUrScript(text, path);
    case Language::kFanucTp: return detail::readFanucTp(text, path);
  }
  return {};
}

std::string writeProgram(const Program& program, std::string_view text,
                         const std::vector<Replacement>& replacements) {
  struct Edit {
    size_t begin, end;
    std::string text;
  };
  std::vector<Edit> edits;
  for (const Replacement& r : replacements) {
    const Target& target = program.targets.at(r.target);
    if (unchangedWithinTolerance(target, r)) continue;
    const std::vector<double> values = newValues(program, target, r);
    STEPCAL_INVARIANT(values.size() == target.fields.size(), "a replacement's size is its target's");
    for (size_t k = 0; k < values.size(); ++k) {
      const NumberField& f = target.fields[k];
      const int decimals = std::max(
          f.decimals, minimumDecimals(program, target.kind == TargetKind::kCartesian && k < 3,
                                      target.kind == TargetKind::kJoint));
      std::string number = formatFixed(values[k], decimals);
      // A4-0.5 written as A4 0.5, never as A40.5: a number that lost its sign stays a token apart.
      if (f.begin > 0 && detail::isWordChar(text[f.begin - 1]) && number[0] != '-') number.insert(0, " ");
      edits.push_back({f.begin, f.end, number});
    }
  }
  std::sort(edits.begin(), edits.end(), [](const Edit& a, const Edit& b) { return a.begin < b.begin; });
  std::string out;
  out.reserve(text.size() + 16 * edits.size());
  size_t at = 0;
  for (const Edit& e : edits) {
    STEPCAL_INVARIANT(e.begin >= at, "the edits do not overlap");
    out.append(text.substr(at, e.begin - at));
    out += e.text;
    at = e.end;
  }
  out.append(text.substr(at));
  return out;
}

int loadIndex(Program& program, const std::string& name, bool any_case) {
  for (size_t i = 0; i < program.loads.size(); ++i) {
    const std::string& n = program.loads[i].name;
    if (any_case ? detail::equalsIgnoringCase(n, name) : n == name) return int(i);
  }
  program.loads.push_back(Load{name, std::nullopt, Vec3::Zero(), ""});
  return int(program.loads.size() - 1);
}

bool unchangedWithinTolerance(const Target& target, const Replacement& r) {
  if (target.kind == TargetKind::kJoint) {
    return r.q_rad.size() == target.q_rad.size() &&
           (r.q_rad - target.q_rad).cwiseAbs().maxCoeff() <= kUnchangedAngle_rad;
  }
  return (r.X_FrameTcp.translation() - target.X_FrameTcp.translation()).norm() <= kUnchangedPosition_m &&
         lie::angleBetween(r.X_FrameTcp.linear(), target.X_FrameTcp.linear()) <= kUnchangedAngle_rad;
}

namespace detail {

Pose poseFromWritten(const std::vector<double>& w, Orientation orientation, double file_units_per_m) {
  Pose X = Pose::Identity();
  X.translation() = Vec3(w[0], w[1], w[2]) / file_units_per_m;
  switch (orientation) {
    case Orientation::kZyxDeg: X.linear() = rotationZyxDeg(w[3], w[4], w[5]); break;
    case Orientation::kFixedXyzDeg: X.linear() = rotationZyxDeg(w[5], w[4], w[3]); break;
    case Orientation::kQuaternionWxyz:
      X.linear() = Eigen::Quaterniond(w[3], w[4], w[5], w[6]).normalized().toRotationMatrix();
      break;
    case Orientation::kRotationVector: {
      const Vec3 v(w[3], w[4], w[5]);
      X.linear() = v.norm() > 0.0 ? Eigen::AngleAxisd(v.norm(), v.normalized()).toRotationMatrix()
                                  : Mat3::Identity();
      break;
    }
  }
  return X;
}

Target cartesianTarget(const Program& program, std::vector<NumberField> fields,
                       std::vector<double> written, int line, int column) {
  Target t;
  t.kind = TargetKind::kCartesian;
  t.line = line;
  t.column = column;
  t.X_FrameTcp = poseFromWritten(written, program.orientation, program.file_units_per_m);
  t.fields = std::move(fields);
  t.written = std::move(written);
  return t;
}

Target jointTarget(const Program& program, std::vector<NumberField> fields,
                   std::vector<double> written, int line, int column) {
  Target t;
  t.kind = TargetKind::kJoint;
  t.line = line;
  t.column = column;
  t.q_rad.resize(long(written.size()));
  for (size_t j = 0; j < written.size(); ++j) t.q_rad[long(j)] = written[j] / program.file_units_per_rad;
  t.fields = std::move(fields);
  t.written = std::move(written);
  return t;
}

}  // namespace detail
}  // namespace stepcal::programs
