// A frame (a tool's TCP in the flange, a work object in the base) in each controller brand's own
// terms, and back: the one home of these conventions (docs/cell.md, "What to enter on the
// pendant"). Sources of the conventions: KUKA XYZ-ABC, R = Rz(A)·Ry(B)·Rx(C), degrees; ABB
// pos + orient, q1 the scalar part (q1..q4 = w, x, y, z), mm; FANUC XYZ-WPR, fixed axes
// x then y then z, R = Rz(R)·Ry(P)·Rx(W), degrees (Roboception rc_visard manual, "Pose
// formats": KUKA, ABB, FANUC); Universal Robots p[x, y, z, rx, ry, rz], m and the rotation vector
// (axis times angle, rad) (UR script manual, "pose").
#pragma once

#include <array>
#include <string>

#include "stepcal/common/types.hpp"

namespace stepcal {

/// KUKA TOOL_DATA / BASE_DATA {X, Y, Z, A, B, C}: mm and degrees, R = Rz(A) Ry(B) Rx(C).
struct KukaFrame {
  double x_mm = 0, y_mm = 0, z_mm = 0, a_deg = 0, b_deg = 0, c_deg = 0;
};
/// ABB tooldata.tframe / wobjdata.uframe [[x, y, z], [q1, q2, q3, q4]]: mm and a unit quaternion,
/// q1 its scalar part, written with q1 ≥ 0.
struct AbbFrame {
  std::array<double, 3> trans_mm{};
  std::array<double, 4> rot_q1234{1, 0, 0, 0};
};
/// Universal Robots TCP / feature pose p[x, y, z, rx, ry, rz]: m and the rotation vector, rad
/// (angle ≤ π).
struct UrFrame {
  std::array<double, 6> pose_m_rad{};
};
/// FANUC UTOOL / UFRAME (X, Y, Z, W, P, R): mm and degrees, fixed axes x, y, z in that order:
/// R = Rz(R) Ry(P) Rx(W).
struct FanucFrame {
  double x_mm = 0, y_mm = 0, z_mm = 0, w_deg = 0, p_deg = 0, r_deg = 0;
};

KukaFrame toKuka(const Pose& X);
Pose fromKuka(const KukaFrame& frame);
AbbFrame toAbb(const Pose& X);
Pose fromAbb(const AbbFrame& frame);
UrFrame toUr(const Pose& X);
Pose fromUr(const UrFrame& frame);
FanucFrame toFanuc(const Pose& X);
Pose fromFanuc(const FanucFrame& frame);

/// The text a pendant or program takes, at 0.001 mm and 0.0001° (UR: 0.000001 m and rad, ABB's
/// quaternion 9 digits): `{X 1.000, Y …, C …}`, `[[1.000,…],[1.000000000,…]]`,
/// `p[0.001000,…]`, `X 1.000 Y … R …`.
std::string kukaText(const KukaFrame& frame);
std::string abbText(const AbbFrame& frame);
std::string urText(const UrFrame& frame);
std::string fanucText(const FanucFrame& frame);

}  // namespace stepcal
