#include "stepcal/common/closed_form_ik.hpp"

#include <algorithm>
#include <array>
#include <cmath>

namespace stepcal {
namespace {

constexpr double kTwoPi = 2.0 * 3.14159265358979323846;
/// How close (m, or the sine of an angle) to a singularity an answer is reported kSingular: well
/// above the √ε ≈ 1e-8 at which the margins' own rounding leaves them.
constexpr double kSingularMargin = 1e-6;
/// Below this the free joint of a singularity is taken from q_near: the other joints' formulas
/// would divide by it.
constexpr double kDegenerate = 1e-12;
/// How far (m) beyond the reach an answer is still taken as the stretched arm (rounding).
constexpr double kReachSlack_m = 1e-9;

Vec3 perpendicular(const Vec3& v, const Vec3& axis) noexcept { return v - axis * axis.dot(v); }

/// An angle as (cos, sin) (ClosedFormInverse::Angle's twin here, free of the class).
struct CosSin {
  double c = 1.0, s = 0.0;
};
CosSin cosSin(double rad) noexcept { return {std::cos(rad), std::sin(rad)}; }
CosSin plus(const CosSin& a, const CosSin& b) noexcept {
  return {a.c * b.c - a.s * b.s, a.s * b.c + a.c * b.s};
}
CosSin minus(const CosSin& a, const CosSin& b) noexcept { return plus(a, {b.c, -b.s}); }
double radians(const CosSin& a) noexcept { return std::atan2(a.s, a.c); }
/// (x, y) scaled onto the unit circle; angle 0 when both vanish.
CosSin unitAngle(double x, double y) noexcept {
  const double r = std::sqrt(x * x + y * y);
  return r > 0.0 ? CosSin{x / r, y / r} : CosSin{};
}

/// Rot(axis, θ) v by Rodrigues' formula (axis unit).
Vec3 rotated(const Vec3& axis, const CosSin& theta, const Vec3& v) noexcept {
  return theta.c * v + theta.s * axis.cross(v) + (1.0 - theta.c) * axis.dot(v) * axis;
}

Mat3 rotation(const Vec3& axis, const CosSin& theta) noexcept {
  Mat3 R = (1.0 - theta.c) * (axis * axis.transpose());
  R.diagonal().array() += theta.c;
  R(0, 1) -= theta.s * axis.z();
  R(1, 0) += theta.s * axis.z();
  R(0, 2) += theta.s * axis.y();
  R(2, 0) -= theta.s * axis.y();
  R(1, 2) -= theta.s * axis.x();
  R(2, 1) += theta.s * axis.x();
  return R;
}

/// Paden–Kahan subproblem 1: the angle about axis that turns u's component ⟂ axis onto v's.
CosSin angleAbout(const Vec3& axis, const Vec3& u, const Vec3& v) noexcept {
  const Vec3 a = perpendicular(u, axis), b = perpendicular(v, axis);
  return unitAngle(a.dot(b), axis.dot(a.cross(b)));
}

/// The screw motion of a revolute joint about the line (axis, point) by θ, as a pose.
Pose screw(const Vec3& axis, const Vec3& point, const CosSin& theta) noexcept {
  Pose E = Pose::Identity();
  E.linear() = rotation(axis, theta);
  E.translation() = point - E.linear() * point;
  return E;
}

double wrapped(double angle_rad) noexcept {
  const double w = std::remainder(angle_rad, kTwoPi);
  return w <= -kTwoPi / 2 ? w + kTwoPi : w;
}

/// The two roots of A cos x + B sin x = D, and how far inside the reach they are: the margin
/// √(ρ² − D²) ≥ 0 (ρ = √(A² + B²)); false when |D| exceeds ρ by more than slack.
bool cosSinRoots(double A, double B, double D, double slack, std::array<CosSin, 2>& roots,
                 double& margin) noexcept {
  const double rho = std::sqrt(A * A + B * B);
  if (std::abs(D) > rho + slack) return false;
  margin = std::sqrt(std::max(0.0, rho * rho - D * D));
  if (rho == 0.0) {
    roots = {CosSin{}, CosSin{}};
    return true;
  }
  // x = φ ± h with (cos φ, sin φ) = (A, B)/ρ and (cos h, sin h) = (D, margin)/ρ.
  const CosSin phi{A / rho, B / rho};
  const CosSin half{std::clamp(D / rho, -1.0, 1.0), margin / rho};
  roots = {plus(phi, half), minus(phi, half)};
  return true;
}

/// Whether two unit axes are parallel (or antiparallel) / perpendicular within the tolerance.
bool parallel(const Vec3& a, const Vec3& b) noexcept {
  return a.cross(b).norm() < ClosedFormInverse::kAngleTolerance;
}
bool perpendicularAxes(const Vec3& a, const Vec3& b) noexcept {
  return std::abs(a.dot(b)) < ClosedFormInverse::kAngleTolerance;
}

/// The point where the lines (a, pa) and (b, pb) meet, when they do (not parallel).
bool meetingPoint(const Vec3& a, const Vec3& pa, const Vec3& b, const Vec3& pb,
                  Vec3& p_Meet) noexcept {
  const Vec3 n = a.cross(b);
  const double n2 = n.squaredNorm();
  if (n2 < ClosedFormInverse::kAngleTolerance * ClosedFormInverse::kAngleTolerance) return false;
  const Vec3 d = pb - pa;
  if (std::abs(d.dot(n)) / std::sqrt(n2) > ClosedFormInverse::kMeetTolerance_m) return false;
  const double ta = d.cross(b).dot(n) / n2, tb = d.cross(a).dot(n) / n2;
  p_Meet = 0.5 * ((pa + ta * a) + (pb + tb * b));
  return true;
}

bool finitePose(const Pose& X) noexcept {
  if (!X.matrix().allFinite()) return false;
  const Mat3& R = X.linear();
  return (R.transpose() * R - Mat3::Identity()).cwiseAbs().maxCoeff() < 1e-9 &&
         R.determinant() > 0.0;
}

ClosedFormStatus worse(ClosedFormStatus a, ClosedFormStatus b) noexcept {
  return static_cast<int>(a) >= static_cast<int>(b) ? a : b;
}

}  // namespace

const char* toString(ArmLayout layout) noexcept {
  switch (layout) {
    case ArmLayout::kSphericalWrist: return "spherical_wrist";
    case ArmLayout::kUniversalRobots: return "universal_robots";
    case ArmLayout::kOther: return "other";
  }
  return "other";
}

const char* toString(ClosedFormStatus status) noexcept {
  switch (status) {
    case ClosedFormStatus::kOk: return "OK";
    case ClosedFormStatus::kSingular: return "SINGULAR";
    case ClosedFormStatus::kUnreachable: return "UNREACHABLE";
    case ClosedFormStatus::kBeyondLimits: return "BEYOND_LIMITS";
    case ClosedFormStatus::kNoClosedForm: return "NO_CLOSED_FORM";
    case ClosedFormStatus::kBadRequest: return "BAD_REQUEST";
  }
  return "UNKNOWN";
}

ClosedFormInverse ClosedFormInverse::recognise(const KinematicChain& chain) noexcept {
  ClosedFormInverse inv;
  if (chain.dof() != 6) return inv;
  ChainWorkspace ws;
  if (!forwardKinematics(chain, JointVector::Zero(6), ws)) return inv;
  for (int i = 0; i < 6; ++i) {
    const Vec6 twist = jointTwistInRoot(chain, ws, i + 1);
    inv.axis_[size_t(i)] = twist.tail<3>().normalized();
    inv.point_[size_t(i)] = inv.axis_[size_t(i)].cross(twist.head<3>());  // v = r × ω
    inv.lower_rad_[size_t(i)] = chain.joints()[size_t(i)].lower_rad;
    inv.upper_rad_[size_t(i)] = chain.joints()[size_t(i)].upper_rad;
  }
  inv.M_ = tipPose(ws);
  const auto& w = inv.axis_;
  const auto& r = inv.point_;
  if (parallel(w[0], w[1]) || !parallel(w[1], w[2]) || !perpendicularAxes(w[4], w[5])) return inv;
  // The arm's plane needs an upper arm and a forearm of some length.
  if (perpendicular(r[2] - r[1], w[1]).norm() < kMeetTolerance_m) return inv;
  ArmLayout layout = ArmLayout::kOther;
  Vec3 p_Wrist;
  if (parallel(w[1], w[3])) {
    if (perpendicularAxes(w[4], w[1]) && meetingPoint(w[4], r[4], w[5], r[5], p_Wrist)) {
      layout = ArmLayout::kUniversalRobots;
      inv.wrist_reference_ = w[1];
    }
  } else if (perpendicularAxes(w[3], w[4])) {
    Vec3 p45, p56;
    if (meetingPoint(w[3], r[3], w[4], r[4], p45) && meetingPoint(w[4], r[4], w[5], r[5], p56) &&
        (p45 - p56).norm() < kMeetTolerance_m) {
      layout = ArmLayout::kSphericalWrist;
      p_Wrist = p56;
      inv.wrist_reference_ = w[3];
    }
  }
  if (layout == ArmLayout::kOther) return inv;
  const Vec3 p_Arm = layout == ArmLayout::kSphericalWrist ? p_Wrist : r[3];
  if (perpendicular(p_Arm - r[2], w[1]).norm() < kMeetTolerance_m) return inv;
  inv.p_Wrist_ = p_Wrist;
  // Up: axis 1 oriented so that axis 2 lies above the root; forward ⟂ axes 1 and 2, towards
  // the wrist at q = 0; a₂ oriented as up × forward.
  const Vec3 up = r[1].dot(w[0]) < 0.0 ? Vec3(-w[0]) : w[0];
  Vec3 forward = w[1].cross(up).normalized();
  if (forward.dot(p_Wrist - r[0]) < 0.0) forward = -forward;
  inv.forward_ = forward;
  inv.arm_axis_ = up.cross(forward).normalized();
  const CosSin phi0 = angleAbout(w[4], inv.wrist_reference_, w[5]);
  inv.wrist_phi0_ = {phi0.c, phi0.s};
  inv.wrist_phi0_rad_ = radians(phi0);
  inv.p_WristInTip_ = inv.M_.inverse() * p_Wrist;
  inv.layout_ = layout;
  return inv;
}

bool ClosedFormInverse::shoulderBack(const Vec3& p_WristAfterJoint1) const noexcept {
  return forward_.dot(p_WristAfterJoint1 - point_[0]) < 0.0;
}

double ClosedFormInverse::elbowSide(const Angle& q3, const Vec3& p_Arm) const noexcept {
  const Vec3& a = axis_[1];
  const Vec3 upper = perpendicular(point_[2] - point_[1], a);
  const Vec3 fore = rotated(axis_[2], {q3.c, q3.s}, perpendicular(p_Arm - point_[2], a));
  return arm_axis_.dot(upper.cross(fore));
}

ClosedFormStatus ClosedFormInverse::solveJoint1(const Vec3& p_WristInBase, bool shoulder_back,
                                                double q_near1, Angle& q1) const noexcept {
  // Joints 2 and 3 (and the UR's 4) turn about parallel axes a₂, which keeps the wrist point's
  // a₂ component: a₂ · Rot(a₁, −q₁)(W − r₁) = a₂ · (w − r₁), w the wrist point at q = 0.
  const Vec3& a1 = axis_[0];
  const Vec3& a2 = axis_[1];
  const Vec3 x = p_WristInBase - point_[0];
  const Vec3 x_across = perpendicular(x, a1);
  const Vec3 x_turned = a1.cross(x_across);  // Rot(a₁, −q)x⊥ = cos q x⊥ − sin q (a₁ × x⊥)
  const double A = a2.dot(x_across), B = -a2.dot(x_turned);
  const double D = a2.dot(p_Wrist_ - point_[0]) - a2.dot(a1) * a1.dot(x);
  std::array<CosSin, 2> roots{};
  double margin = 0.0;
  if (!cosSinRoots(A, B, D, kReachSlack_m, roots, margin)) return ClosedFormStatus::kUnreachable;
  if (std::sqrt(A * A + B * B) < kDegenerate) {  // the wrist point on axis 1: any q1
    const CosSin near = cosSin(q_near1);
    q1 = {near.c, near.s};
    return ClosedFormStatus::kSingular;
  }
  // The root on the requested side of axis 1 (forward ⟂ a₁: its coordinate ±margin).
  const double sign = shoulder_back ? -1.0 : 1.0;
  const auto ahead = [&](const CosSin& q) {
    return sign * (q.c * forward_.dot(x_across) - q.s * forward_.dot(x_turned));
  };
  const CosSin& chosen = ahead(roots[0]) >= ahead(roots[1]) ? roots[0] : roots[1];
  q1 = {chosen.c, chosen.s};
  return margin < kSingularMargin ? ClosedFormStatus::kSingular : ClosedFormStatus::kOk;
}

ClosedFormStatus ClosedFormInverse::solveArmPlane(const Vec3& p_TargetAfterJoint1,
                                                  const Vec3& p_Arm, bool elbow_down, Angle& q2,
                                                  Angle& q3) const noexcept {
  // Subproblem 3: turn p_Arm about axis 3 until its distance from axis 2 is the target's.
  const Vec3& a = axis_[1];
  const Vec3 upper = perpendicular(point_[2] - point_[1], a);
  const Vec3 fore = perpendicular(p_Arm - point_[2], a);
  const double reach2 = perpendicular(p_TargetAfterJoint1 - point_[1], a).squaredNorm();
  const double A = upper.dot(fore), B = upper.dot(axis_[2].cross(fore));
  const double D = 0.5 * (reach2 - upper.squaredNorm() - fore.squaredNorm());
  const double scale_m = std::max(upper.norm(), fore.norm());
  std::array<CosSin, 2> roots{};
  double margin = 0.0;
  if (!cosSinRoots(A, B, D, kReachSlack_m * scale_m, roots, margin)) {
    return ClosedFormStatus::kUnreachable;
  }
  // The root on the requested side of the line through axes 2 and 3.
  const double sign = elbow_down ? -1.0 : 1.0;
  const Angle r0{roots[0].c, roots[0].s}, r1{roots[1].c, roots[1].s};
  q3 = sign * elbowSide(r0, p_Arm) >= sign * elbowSide(r1, p_Arm) ? r0 : r1;
  // Subproblem 1: turn the elbow's point about axis 2 onto the target.
  const Vec3 p_Elbowed = rotated(axis_[2], {q3.c, q3.s}, p_Arm - point_[2]) + point_[2];
  const CosSin turn = angleAbout(axis_[1], p_Elbowed - point_[1], p_TargetAfterJoint1 - point_[1]);
  q2 = {turn.c, turn.s};
  return margin < kSingularMargin * scale_m ? ClosedFormStatus::kSingular : ClosedFormStatus::kOk;
}

namespace {

/// q5 of a wrist whose reference axis (axis 4, the UR: axis 2) makes the angle θ with axis 6
/// (y: axis 6 as the pose turns it): ±θ − φ₀, with θ's cosine and sine from the dot and cross
/// products (exact near the singularity, where acos is not); sin θ returned too.
CosSin wristJoint5(const Vec3& reference, const Vec3& y, bool flipped, const CosSin& phi0,
                   double& sin_theta) noexcept {
  sin_theta = reference.cross(y).norm();
  const CosSin theta = unitAngle(reference.dot(y), sin_theta);
  return minus(flipped ? CosSin{theta.c, -theta.s} : theta, phi0);
}

}  // namespace

ClosedFormStatus ClosedFormInverse::solveSpherical(const Pose& X_BaseTip, ArmBranch branch,
                                                   const JointVector* q_near,
                                                   JointVector& q) const noexcept {
  const auto near = [&](int j) { return q_near ? (*q_near)(j) : 0.0; };
  const Vec3 p_WristInBase = X_BaseTip * p_WristInTip_;
  Angle q1, q2, q3;
  ClosedFormStatus status = solveJoint1(p_WristInBase, branch.shoulder_back, near(0), q1);
  if (status == ClosedFormStatus::kUnreachable) return status;
  const Vec3 p_AfterJoint1 =
      rotated(axis_[0], {q1.c, -q1.s}, p_WristInBase - point_[0]) + point_[0];
  const ClosedFormStatus arm = solveArmPlane(p_AfterJoint1, p_Wrist_, branch.elbow_down, q2, q3);
  if (arm == ClosedFormStatus::kUnreachable) return arm;
  status = worse(status, arm);
  // The wrist: R4 R5 R6 = (R1 R2 R3)ᵀ R_X R_Mᵀ.
  const Mat3 R123 = rotation(axis_[0], {q1.c, q1.s}) * rotation(axis_[1], {q2.c, q2.s}) *
                    rotation(axis_[2], {q3.c, q3.s});
  const Mat3 R_wrist = R123.transpose() * X_BaseTip.linear() * M_.linear().transpose();
  const Vec3& w4 = axis_[3];
  const Vec3& w5 = axis_[4];
  const Vec3& w6 = axis_[5];
  const Vec3 y = R_wrist * w6;
  double sin_theta = 0.0;
  const CosSin q5 = wristJoint5(w4, y, branch.wrist_flipped, {wrist_phi0_.c, wrist_phi0_.s},
                                sin_theta);
  const CosSin q4 = sin_theta < kDegenerate ? cosSin(near(3)) : angleAbout(w4, rotated(w5, q5, w6), y);
  const Mat3 R45 = rotation(w4, q4) * rotation(w5, q5);
  const CosSin q6 = angleAbout(w6, w5, R45.transpose() * R_wrist * w5);
  if (sin_theta < kSingularMargin) status = worse(status, ClosedFormStatus::kSingular);
  q.resize(6);
  q << radians({q1.c, q1.s}), radians({q2.c, q2.s}), radians({q3.c, q3.s}), radians(q4),
      radians(q5), radians(q6);
  return status;
}

ClosedFormStatus ClosedFormInverse::solveUniversal(const Pose& X_BaseTip, ArmBranch branch,
                                                   const JointVector* q_near,
                                                   JointVector& q) const noexcept {
  const auto near = [&](int j) { return q_near ? (*q_near)(j) : 0.0; };
  const Vec3 p_WristInBase = X_BaseTip * p_WristInTip_;
  Angle q1;
  ClosedFormStatus status = solveJoint1(p_WristInBase, branch.shoulder_back, near(0), q1);
  if (status == ClosedFormStatus::kUnreachable) return status;
  // Rot(a₂, θ₂₃₄) R5 R6 = R1ᵀ R_X R_Mᵀ; a₂ is kept by the first factor.
  const Vec3& a2 = axis_[1];
  const Vec3& w5 = axis_[4];
  const Vec3& w6 = axis_[5];
  const Mat3 R_rest = rotation(axis_[0], {q1.c, q1.s}).transpose() * X_BaseTip.linear() *
                      M_.linear().transpose();
  const Vec3 y = R_rest * w6;
  double sin_theta = 0.0;
  const CosSin q5 = wristJoint5(a2, y, branch.wrist_flipped, {wrist_phi0_.c, wrist_phi0_.s},
                                sin_theta);
  const Mat3 R5 = rotation(w5, q5);
  // a₂ᵀ R5 R6 = a₂ᵀ R_rest, i.e. R6 (R_restᵀ a₂) = R5ᵀ a₂.
  const CosSin q6 = sin_theta < kDegenerate
                        ? cosSin(near(5))
                        : angleAbout(w6, R_rest.transpose() * a2, R5.transpose() * a2);
  const Mat3 R56 = R5 * rotation(w6, q6);
  const CosSin theta234 = angleAbout(a2, w5, R_rest * R56.transpose() * w5);
  if (sin_theta < kSingularMargin) status = worse(status, ClosedFormStatus::kSingular);
  // E2 E3 E4 = E1⁻¹ X M⁻¹ (E5 E6)⁻¹ moves axis 4's points as E2 E3 does.
  const Pose E56 = screw(w5, point_[4], q5) * screw(w6, point_[5], q6);
  const Pose G = screw(axis_[0], point_[0], {q1.c, -q1.s}) * X_BaseTip * M_.inverse() *
                 E56.inverse();
  Angle q2, q3;
  const ClosedFormStatus arm =
      solveArmPlane(G * point_[3], point_[3], branch.elbow_down, q2, q3);
  if (arm == ClosedFormStatus::kUnreachable) return arm;
  status = worse(status, arm);
  const double q2_rad = radians({q2.c, q2.s}), q3_rad = radians({q3.c, q3.s});
  const double s3 = axis_[2].dot(a2), s4 = axis_[3].dot(a2);
  const double q4_rad = s4 * (radians(theta234) - q2_rad - s3 * q3_rad);
  q.resize(6);
  q << radians({q1.c, q1.s}), q2_rad, q3_rad, q4_rad, radians(q5), radians(q6);
  return status;
}

ClosedFormStatus ClosedFormInverse::solveBranch(const Pose& X_BaseTip, ArmBranch branch,
                                                const JointVector* q_near, bool within_limits,
                                                JointVector& q_out) const noexcept {
  if (layout_ == ArmLayout::kOther) return ClosedFormStatus::kNoClosedForm;
  if (!finitePose(X_BaseTip) || (q_near && (q_near->size() != 6 || !q_near->allFinite()))) {
    return ClosedFormStatus::kBadRequest;
  }
  JointVector q(6);
  const ClosedFormStatus status = layout_ == ArmLayout::kSphericalWrist
                                      ? solveSpherical(X_BaseTip, branch, q_near, q)
                                      : solveUniversal(X_BaseTip, branch, q_near, q);
  if (status == ClosedFormStatus::kUnreachable) return status;
  bool beyond = false;
  for (int j = 0; j < 6; ++j) {
    if (!q_near) {
      q(j) = wrapped(q(j));
      continue;
    }
    // The whole turn nearest q_near within the limits (when asked), else nearest q_near.
    const double base = q(j) + kTwoPi * std::round(((*q_near)(j) - q(j)) / kTwoPi);
    const bool inside = base >= lower_rad_[size_t(j)] - kDegenerate &&
                        base <= upper_rad_[size_t(j)] + kDegenerate;
    double best = base, best_distance = HUGE_VAL;
    for (int k = -2; k <= 2 && within_limits; ++k) {
      const double candidate = base + k * kTwoPi;
      const double distance = std::abs(candidate - (*q_near)(j));
      if (candidate >= lower_rad_[size_t(j)] - kDegenerate &&
          candidate <= upper_rad_[size_t(j)] + kDegenerate && distance < best_distance) {
        best = candidate;
        best_distance = distance;
      }
    }
    beyond = beyond || (within_limits ? best_distance == HUGE_VAL : !inside);
    q(j) = best;
  }
  q_out = q;
  return beyond ? worse(status, ClosedFormStatus::kBeyondLimits) : status;
}

int ClosedFormInverse::solveAll(const Pose& X_BaseTip, std::array<JointVector, 8>& q_out,
                                std::array<ArmBranch, 8>& branch_out) const noexcept {
  int count = 0;
  for (int index = 0; index < 8; ++index) {
    const ArmBranch branch = ArmBranch::fromIndex(index);
    const ClosedFormStatus status = solveBranch(X_BaseTip, branch, nullptr, true, q_out[size_t(count)]);
    if (status == ClosedFormStatus::kOk || status == ClosedFormStatus::kSingular) {
      branch_out[size_t(count++)] = branch;
    }
  }
  return count;
}

ClosedFormStatus ClosedFormInverse::solve(const Pose& X_BaseTip, ArmBranch branch,
                                          const JointVector& q_near,
                                          JointVector& q_out) const noexcept {
  return solveBranch(X_BaseTip, branch, &q_near, true, q_out);
}

ClosedFormStatus ClosedFormInverse::solveNearest(const Pose& X_BaseTip, ArmBranch branch,
                                                 const JointVector& q_near,
                                                 JointVector& q_out) const noexcept {
  return solveBranch(X_BaseTip, branch, &q_near, false, q_out);
}

ArmBranch ClosedFormInverse::branchOf(const JointVector& q) const noexcept {
  ArmBranch branch;
  if (layout_ == ArmLayout::kOther || q.size() != 6) return branch;
  // The wrist point with joint 1 undone: E2 E3 w (the UR: E2 E3 E4 w, E5 keeps it).
  Vec3 p = p_Wrist_;
  if (layout_ == ArmLayout::kUniversalRobots) p = screw(axis_[3], point_[3], cosSin(q(3))) * p;
  p = screw(axis_[1], point_[1], cosSin(q(1))) * (screw(axis_[2], point_[2], cosSin(q(2))) * p);
  branch.shoulder_back = shoulderBack(p);
  const CosSin q3 = cosSin(q(2));
  branch.elbow_down =
      elbowSide({q3.c, q3.s}, layout_ == ArmLayout::kSphericalWrist ? p_Wrist_ : point_[3]) < 0.0;
  branch.wrist_flipped = std::sin(q(4) + wrist_phi0_rad_) < 0.0;
  return branch;
}

}  // namespace stepcal
