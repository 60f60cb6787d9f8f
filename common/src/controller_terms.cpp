#include "stepcal/common/controller_terms.hpp"

#include <cmath>
#include <cstdio>

#include "stepcal/common/lie.hpp"
#include "stepcal/common/units.hpp"

namespace stepcal {
namespace {

Pose poseAt(double x_m, double y_m, double z_m, const Mat3& R) {
  Pose X = Pose::Identity();
  X.linear() = R;
  X.translation() = Vec3(x_m, y_m, z_m);
  return X;
}

/// v rounded to `decimals` places, so that a value that prints as zero prints without a sign
/// ("0.0000", never "-0.0000", which a pendant would take as typed).
double shown(double v, int decimals) {
  const double scale = std::pow(10.0, decimals);
  const double rounded = std::round(v * scale) / scale;
  return rounded == 0.0 ? 0.0 : rounded;
}

}  // namespace

// KUKA's A, B, C are the URDF's yaw, pitch, roll: R = Rz(A) Ry(B) Rx(C).
KukaFrame toKuka(const Pose& X) {
  const Vec3 rpy = lie::rpyFromRotation(X.linear());
  const Vec3 p_mm = X.translation() * kMmPerM;
  return {p_mm.x(), p_mm.y(), p_mm.z(), rpy[2] * kDegPerRad, rpy[1] * kDegPerRad,
          rpy[0] * kDegPerRad};
}

Pose fromKuka(const KukaFrame& f) {
  return poseAt(f.x_mm * kMPerMm, f.y_mm * kMPerMm, f.z_mm * kMPerMm,
                lie::rotationFromRpy(f.c_deg * kRadPerDeg, f.b_deg * kRadPerDeg,
                                     f.a_deg * kRadPerDeg));
}

AbbFrame toAbb(const Pose& X) {
  Eigen::Quaterniond q(X.linear());
  if (q.w() < 0) q.coeffs() = -q.coeffs();  // the same rotation; ABB's own tables write q1 ≥ 0
  AbbFrame out;
  for (int k = 0; k < 3; ++k) out.trans_mm[size_t(k)] = X.translation()[k] * kMmPerM;
  out.rot_q1234 = {q.w(), q.x(), q.y(), q.z()};
  return out;
}

Pose fromAbb(const AbbFrame& f) {
  const Eigen::Quaterniond q(f.rot_q1234[0], f.rot_q1234[1], f.rot_q1234[2], f.rot_q1234[3]);
  return poseAt(f.trans_mm[0] * kMPerMm, f.trans_mm[1] * kMPerMm, f.trans_mm[2] * kMPerMm,
                q.normalized().toRotationMatrix());
}

UrFrame toUr(const Pose& X) {
  const Vec3 r = lie::logSO3(X.linear());
  const Vec3& p = X.translation();
  return {{p.x(), p.y(), p.z(), r.x(), r.y(), r.z()}};
}

Pose fromUr(const UrFrame& f) {
  const auto& v = f.pose_m_rad;
  return poseAt(v[0], v[1], v[2], lie::expSO3(Vec3(v[3], v[4], v[5])));
}

// FANUC's W, P, R are the URDF's roll, pitch, yaw.
FanucFrame toFanuc(const Pose& X) {
  const Vec3 rpy = lie::rpyFromRotation(X.linear());
  const Vec3 p_mm = X.translation() * kMmPerM;
  return {p_mm.x(), p_mm.y(), p_mm.z(), rpy[0] * kDegPerRad, rpy[1] * kDegPerRad,
          rpy[2] * kDegPerRad};
}

Pose fromFanuc(const FanucFrame& f) {
  return poseAt(f.x_mm * kMPerMm, f.y_mm * kMPerMm, f.z_mm * kMPerMm,
                lie::rotationFromRpy(f.w_deg * kRadPerDeg, f.p_deg * kRadPerDeg,
                                     f.r_deg * kRadPerDeg));
}

std::string kukaText(const KukaFrame& f) {
  char text[200];
  std::snprintf(text, sizeof text, "{X %.3f, Y %.3f, Z %.3f, A %.4f, B %.4f, C %.4f}",
                shown(f.x_mm, 3), shown(f.y_mm, 3), shown(f.z_mm, 3), shown(f.a_deg, 4),
                shown(f.b_deg, 4), shown(f.c_deg, 4));
  return text;
}

std::string abbText(const AbbFrame& f) {
  char text[200];
  std::snprintf(text, sizeof text, "[[%.3f,%.3f,%.3f],[%.9f,%.9f,%.9f,%.9f]]",
                shown(f.trans_mm[0], 3), shown(f.trans_mm[1], 3), shown(f.trans_mm[2], 3),
                shown(f.rot_q1234[0], 9), shown(f.rot_q1234[1], 9), shown(f.rot_q1234[2], 9),
                shown(f.rot_q1234[3], 9));
  return text;
}

std::string urText(const UrFrame& f) {
  const auto& v = f.pose_m_rad;
  char text[200];
  std::snprintf(text, sizeof text, "p[%.6f, %.6f, %.6f, %.6f, %.6f, %.6f]", shown(v[0], 6),
                shown(v[1], 6), shown(v[2], 6), shown(v[3], 6), shown(v[4], 6), shown(v[5], 6));
  return text;
}

std::string fanucText(const FanucFrame& f) {
  char text[200];
  std::snprintf(text, sizeof text, "X %.3f Y %.3f Z %.3f W %.4f P %.4f R %.4f", shown(f.x_mm, 3),
                shown(f.y_mm, 3), shown(f.z_mm, 3), shown(f.w_deg, 4), shown(f.p_deg, 4),
                shown(f.r_deg, 4));
  return text;
}

}  // namespace stepcal
