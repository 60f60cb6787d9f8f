// `stepcal frame MODEL POINTS [--tool TOOL.json] [--out FRAME.json]`: a work object (base, user
// frame) with the calibrated robot, by the three-point method or a least-squares fit to
// fiducials of known coordinates, touched with the calibrated TCP or measured by the tracker; in
// every controller's terms with its 1-σ (docs/cell.md).
#include <cmath>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "stepcal/common/atomic_file.hpp"
#include "stepcal/common/controller_terms.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/pose_quaternion.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/report/text_format.hpp"
#include "stepcal/trainer/cell.hpp"
#include "subcommands.hpp"
#include "tool_file.hpp"
#include "touch_file.hpp"

namespace stepcal::cli {
namespace {

using report::format;

struct FrameArgs {
  std::string model, points, tool, out;
  double tracker_sigma_mm = 0.015;  ///< a tracker-measured point's stated σ per axis
  double payload_kg = -1;
  std::vector<double> cog_mm{0, 0, 0};
};

/// Each line's point in the tracker frame: measured, or touched with the TCP.
std::vector<trainer::FramePoint> framePoints(const FrameArgs& a, const runtime::RuntimeModel& model,
                                             const std::vector<Touch>& touches,
                                             const std::optional<ToolFile>& tool) {
  std::optional<runtime::Payload> payload;
  if (a.payload_kg >= 0) {
    payload = runtime::Payload{a.payload_kg, Vec3(a.cog_mm[0], a.cog_mm[1], a.cog_mm[2]) * kMPerMm,
                               runtime::CogFrame::kFlange};
  }
  std::vector<trainer::FramePoint> points;
  for (const Touch& t : touches) {
    trainer::FramePoint point;
    if (t.p_InTracker_m) {
      point.p_InTracker_m = *t.p_InTracker_m;
    } else {
      if (!tool) {
        throw InputError("a touch (joints, no measured point) needs the calibrated TCP; expected "
                         "--tool TOOL.json (stepcal tool --out)", a.points, t.line);
      }
      const Pose X = touchPoses(model, {t}, payload, a.points).front();
      point.p_InTracker_m = X * tool->p_TcpInTip_m;
      point.dPointdTcp = X.linear();
    }
    points.push_back(point);
  }
  return points;
}

trainer::FrameFit fitPoints(const FrameArgs& a, const std::vector<Touch>& touches,
                            const std::vector<trainer::FramePoint>& points, double sigma_m,
                            const Mat3& covariance_tool, std::string& method) {
  if (!touches.front().point.empty()) {
    method = "three-point";
    std::optional<trainer::FramePoint> origin, on_x, in_xy;
    for (size_t i = 0; i < touches.size(); ++i) {
      auto& slot = touches[i].point == "origin" ? origin : touches[i].point == "x" ? on_x : in_xy;
      if (slot) throw InputError("a second '" + touches[i].point + "' point; expected each of origin, x, xy once", a.points, touches[i].line, "point");
      slot = points[i];
    }
    if (!origin || !on_x || !in_xy) {
      throw InputError("the three-point method needs one point each of origin, x and xy", a.points);
    }
    return trainer::fitFrameFromThreePoints(*origin, *on_x, *in_xy, sigma_m, covariance_tool);
  }
  method = "least squares";
  std::vector<Vec3> nominal;
  for (const Touch& t : touches) {
    if (!t.p_NominalInFrame_m) {
      throw InputError("no nominal coordinates; expected nx_mm ny_mm nz_mm (the fiducial in the "
                       "frame) or a point column (origin, x, xy)", a.points, t.line, "nx_mm");
    }
    nominal.push_back(*t.p_NominalInFrame_m);
  }
  return trainer::fitFrameToFiducials(points, nominal, sigma_m, covariance_tool);
}

int runFrame(const FrameArgs& a) {
  const std::unique_ptr<const runtime::RuntimeModel> model = runtime::RuntimeModel::load(a.model);
  const std::vector<Touch> touches = readTouchFile(a.points, int(model->file.chain_Tracker.dof()));
  std::optional<ToolFile> tool;
  if (!a.tool.empty()) tool = readToolFile(a.tool, *model, a.model);
  const std::vector<trainer::FramePoint> points = framePoints(a, *model, touches, tool);
  const bool touched = !touches.front().p_InTracker_m;
  // A touch scatters as the tool's own touches did; a tracker point by the tracker's noise.
  const double sigma_m = touched ? std::max(tool->point_sigma_m, modelPointSigma(model->file))
                                 : a.tracker_sigma_mm * kMPerMm;
  const Mat3 covariance_tool = tool ? tool->covariance_m2 : Mat3::Zero();
  std::string method;
  const trainer::FrameFit fit = fitPoints(a, touches, points, sigma_m, covariance_tool, method);
  std::cout << "work object by " << method << " from " << fit.points << " points of " << a.points
            << (touched ? " touched with the TCP of " + a.tool : " measured by the tracker") << "\n";
  if (!fit.note.empty()) {
    std::cout << "  no frame: " << fit.note << "\n";
    return exit_code::kDone;
  }
  const Pose X_BaseFrame = model->file.X_TrackerBase.inverse() * fit.X_TrackerFrame;
  Vec6 sigma;
  for (int k = 0; k < 6; ++k) sigma[k] = std::sqrt(fit.covariance(k, k));
  std::cout << format("  1-sigma: origin %.4f %.4f %.4f mm, rotation %.5f %.5f %.5f deg (along and "
                      "about the frame's own x y z); point scatter %.4f mm, residual rms %.4f mm\n",
                      sigma[0] * kMmPerM, sigma[1] * kMmPerM, sigma[2] * kMmPerM,
                      sigma[3] * kDegPerRad, sigma[4] * kDegPerRad, sigma[5] * kDegPerRad,
                      fit.point_sigma_m * kMmPerM, fit.rms_residual_m * kMmPerM);
  std::cout << "the controller's work object (in the robot's base frame, where the model registered "
               "the nominal robot):\n"
            << "  KUKA BASE_DATA   " << kukaText(toKuka(X_BaseFrame)) << "\n"
            << "  ABB wobjdata.uframe " << abbText(toAbb(X_BaseFrame)) << "\n"
            << "  UR feature       " << urText(toUr(X_BaseFrame)) << "\n"
            << "  FANUC UFRAME     " << fanucText(toFanuc(X_BaseFrame)) << "\n";
  const AbbFrame abb = toAbb(X_BaseFrame);  // mm and the quaternion with qw ≥ 0
  const std::string user_frame =
      format("%.4f %.4f %.4f %.9f %.9f %.9f %.9f", abb.trans_mm[0], abb.trans_mm[1],
             abb.trans_mm[2], abb.rot_q1234[0], abb.rot_q1234[1], abb.rot_q1234[2], abb.rot_q1234[3]);
  std::cout << "for the runtime and stepcal correct: --frame user --user-frame " << user_frame << "\n";
  if (!a.out.empty()) {
    nlohmann::json out = {
        {"format", "stepcal-frame/1"}, {"model", a.model}, {"points", a.points},
        {"method", method}, {"user_frame", user_frame},
        {"sigma_origin_mm", {sigma[0] * kMmPerM, sigma[1] * kMmPerM, sigma[2] * kMmPerM}},
        {"sigma_rotation_deg", {sigma[3] * kDegPerRad, sigma[4] * kDegPerRad, sigma[5] * kDegPerRad}},
        {"controller", {{"kuka", kukaText(toKuka(X_BaseFrame))}, {"abb", abbText(toAbb(X_BaseFrame))},
                        {"ur", urText(toUr(X_BaseFrame))}, {"fanuc", fanucText(toFanuc(X_BaseFrame))}}}};
    const std::string text = out.dump(2) + "\n";
    writeFileAtomically(a.out, text.data(), text.size(), "frame file");
    std::cerr << "wrote " << a.out << "\n";
  }
  return exit_code::kDone;
}

}  // namespace

Subcommand addFrameCommand(CLI::App& app) {
  auto args = std::make_shared<FrameArgs>();
  FrameArgs& a = *args;
  CLI::App* cmd = app.add_subcommand(
      "frame", "a work object (base, user frame) with the calibrated robot: three points "
               "(column point: origin, x, xy) or a least-squares fit to fiducials (nx_mm ny_mm "
               "nz_mm), touched with the calibrated TCP or measured by the tracker; KUKA, ABB, UR "
               "and FANUC terms with 1-sigma (docs/cell.md)");
  cmd->add_option("model", a.model, "model file")->required();
  cmd->add_option("points", a.points, "touch file (CSV)")->required();
  cmd->add_option("--tool", a.tool, "the calibrated TCP (stepcal tool --out), for touched points");
  cmd->add_option("--out", a.out, "frame file to write (JSON)");
  cmd->add_option("--tracker-sigma-mm", a.tracker_sigma_mm,
                  "a tracker-measured point's 1-sigma per axis, mm (default 0.015)");
  cmd->add_option("--payload", a.payload_kg, "the tool's mass during the touches, kg");
  cmd->add_option("--cog", a.cog_mm, "its centre of gravity in the flange frame, mm")->expected(3);
  return {cmd, [args] { return runFrame(*args); }};
}

}  // namespace stepcal::cli
