// `stepcal tool MODEL TOUCHES|CAMPAIGN [--out TOOL.json]`: the tool's centre point (TCP) with the calibrated
// robot, from tracker shots at it or from the four-point method, in every controller's terms
// with its 1-σ; its axes measured when a campaign's rows carry the TCP's orientation, else
// --rotation's (docs/cell.md).
#include <algorithm>
#include <cmath>
#include <filesystem>
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

struct ToolArgs {
  std::string model, touches, out;
  std::vector<double> rotation{1, 0, 0, 0};  ///< the TCP's axes in the flange's: qw qx qy qz
  bool rotation_given = false;               ///< --rotation on the command line
  double payload_kg = -1;                    ///< < 0: none given
  std::vector<double> cog_mm{0, 0, 0};       ///< in the flange frame
};

nlohmann::json poseJson(const Pose& X) {
  double p_m[3], q[4];
  toPositionQuaternion(X, p_m, q);
  return {{"x_mm", p_m[0] * kMmPerM}, {"y_mm", p_m[1] * kMmPerM}, {"z_mm", p_m[2] * kMmPerM},
          {"qw", q[0]}, {"qx", q[1]}, {"qy", q[2]}, {"qz", q[3]}};
}

nlohmann::json matrixJson(const Mat3& M) {
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 3; ++r) rows.push_back({M(r, 0), M(r, 1), M(r, 2)});
  return rows;
}

std::string sigmaText(const Mat3& covariance_m2) {
  return format("%.4f %.4f %.4f", std::sqrt(covariance_m2(0, 0)) * kMmPerM,
                std::sqrt(covariance_m2(1, 1)) * kMmPerM, std::sqrt(covariance_m2(2, 2)) * kMmPerM);
}

nlohmann::json controllerJson(const Pose& X) {
  return {{"kuka", kukaText(toKuka(X))}, {"abb", abbText(toAbb(X))}, {"ur", urText(toUr(X))},
          {"fanuc", fanucText(toFanuc(X))}};
}

/// A pose as a correction program's tool columns take it: x,y,z (mm),qw,qx,qy,qz.
std::string toolColumns(const Pose& X) {
  double p_m[3], q[4];
  toPositionQuaternion(X, p_m, q);
  return format("%.4f,%.4f,%.4f,%.9f,%.9f,%.9f,%.9f", p_m[0] * kMmPerM, p_m[1] * kMmPerM,
                p_m[2] * kMmPerM, q[0], q[1], q[2], q[3]);
}

void printController(const char* what, const Pose& X) {
  std::cout << what << ":\n"
            << "  KUKA   " << kukaText(toKuka(X)) << "\n"
            << "  ABB    " << abbText(toAbb(X)) << "\n"
            << "  UR     " << urText(toUr(X)) << "\n"
            << "  FANUC  " << fanucText(toFanuc(X)) << "\n";
}

trainer::ToolPointFit fitTouches(const ToolArgs& a, const runtime::RuntimeModel& model,
                                 const std::vector<Touch>& touches, double model_sigma_m,
                                 std::string& method, std::vector<Pose>& X_TrackerTip) {
  std::optional<runtime::Payload> payload;
  if (a.payload_kg >= 0) {
    payload = runtime::Payload{a.payload_kg, Vec3(a.cog_mm[0], a.cog_mm[1], a.cog_mm[2]) * kMPerMm,
                               runtime::CogFrame::kFlange};
  }
  X_TrackerTip = touchPoses(model, touches, payload, a.touches);
  const bool tracker = touches.front().p_InTracker_m.has_value();
  std::vector<Vec3> measured;
  for (const Touch& t : touches) {
    if (t.p_InTracker_m.has_value() != tracker) {
      throw InputError(std::string("this line ") + (tracker ? "has no" : "has a") +
                           " measured point while the first has " + (tracker ? "one" : "none") +
                           "; expected tracker rows (joints and x_mm …) or touches (joints only) "
                           "throughout",
                       a.touches, t.line, "x_mm");
    }
    if (tracker) measured.push_back(*t.p_InTracker_m);
  }
  method = tracker ? "tracker" : "four-point";
  return tracker ? trainer::fitToolFromTracker(X_TrackerTip, measured, model_sigma_m)
                 : trainer::fitToolFromFixedPoint(X_TrackerTip, model_sigma_m);
}

/// The TCP's axes in the target's: measured when every row gives the TCP's orientation (a
/// campaign of a 6-D target at the TCP) and --rotation is not given, else --rotation's (the
/// flange's axes by default) turned into the target's.
struct TcpAxes {
  Mat3 R_TipTcp = Mat3::Identity();
  std::optional<trainer::ToolOrientationFit> measured;
};

TcpAxes tcpAxes(const ToolArgs& a, const runtime::RuntimeModel& model,
                const std::vector<Touch>& touches, const std::vector<Pose>& X_TrackerTip) {
  TcpAxes axes;
  const bool all_oriented = std::all_of(touches.begin(), touches.end(),
                                        [](const Touch& t) { return t.R_TrackerTcp.has_value(); });
  if (all_oriented && !a.rotation_given) {
    std::vector<Mat3> R_TrackerTcp;
    for (const Touch& t : touches) R_TrackerTcp.push_back(*t.R_TrackerTcp);
    axes.measured =
        trainer::fitToolOrientation(X_TrackerTip, R_TrackerTcp, modelOrientationSigma(model.file));
    axes.R_TipTcp = axes.measured->R_TipTcp;
    return axes;
  }
  const Eigen::Quaterniond q_FlangeTcp(a.rotation[0], a.rotation[1], a.rotation[2], a.rotation[3]);
  if (!isUnitQuaternion(q_FlangeTcp)) {
    throw InputError("--rotation " + format("%g %g %g %g", a.rotation[0], a.rotation[1],
                                            a.rotation[2], a.rotation[3]) +
                     " is not a unit quaternion (qw qx qy qz); expected norm 1 within 1e-6");
  }
  // Given in the flange's axes; from the target they turn by the flange's rotation.
  const Mat3 R_TipFlange = model.has_flange ? Mat3(model.X_TipFlange.linear()) : Mat3::Identity();
  axes.R_TipTcp = R_TipFlange * q_FlangeTcp.normalized().toRotationMatrix();
  return axes;
}

void printMeasuredAxes(const trainer::ToolOrientationFit& fit, nlohmann::json& out) {
  const Eigen::Quaterniond q(fit.R_TipTcp);
  const double sigma_deg = std::sqrt(fit.covariance_rad2(0, 0)) * kDegPerRad;
  std::cout << format("  axes measured from %d rows: qw qx qy qz %.9f %.9f %.9f %.9f (target "
                      "axes), 1-sigma %.5f deg about each TCP axis; residual rms %.5f deg\n",
                      fit.points, q.w(), q.x(), q.y(), q.z(), sigma_deg,
                      fit.rms_residual_rad * kDegPerRad);
  out["tcp_axes_from"] = "measured";
  out["tcp_orientation_sigma_deg"] = {sigma_deg, sigma_deg, sigma_deg};
  out["orientation_rms_residual_deg"] = fit.rms_residual_rad * kDegPerRad;
}

int runTool(const ToolArgs& a) {
  const std::unique_ptr<const runtime::RuntimeModel> model = runtime::RuntimeModel::load(a.model);
  const std::vector<Touch> touches =
      std::filesystem::is_directory(a.touches)
          ? readCampaignShots(a.touches, model->file, a.model)
          : readTouchFile(a.touches, int(model->file.chain_Tracker.dof()));
  const double model_sigma_m = modelPointSigma(model->file);
  std::string method;
  std::vector<Pose> X_TrackerTip;
  const trainer::ToolPointFit fit =
      fitTouches(a, *model, touches, model_sigma_m, method, X_TrackerTip);
  const TcpAxes axes = tcpAxes(a, *model, touches, X_TrackerTip);
  Pose X_TipTcp = Pose::Identity();
  X_TipTcp.linear() = axes.R_TipTcp;
  X_TipTcp.translation() = fit.p_TcpInTip_m;

  std::cout << "TCP by the " << method << " method from " << fit.points << " "
            << (method == "tracker" ? "tracker rows" : "touches") << " of " << a.touches << "\n"
            << format("  on the measured target: %.4f %.4f %.4f mm, 1-sigma %s mm (target axes)\n",
                      fit.p_TcpInTip_m.x() * kMmPerM, fit.p_TcpInTip_m.y() * kMmPerM,
                      fit.p_TcpInTip_m.z() * kMmPerM, sigmaText(fit.covariance_TcpInTip_m2).c_str())
            << format("  residual rms %.4f mm over %d points; one point's scatter %.4f mm per axis "
                      "(the model's own %.4f mm); orientations spread %.1f deg at least\n",
                      fit.rms_residual_m * kMmPerM, fit.points, fit.point_sigma_m * kMmPerM,
                      model_sigma_m * kMmPerM, fit.least_spread_rad * kDegPerRad);
  if (method == "four-point") {
    std::cout << format("  the touched point, tracker frame: %.4f %.4f %.4f mm\n",
                        fit.p_FixedInTracker_m.x() * kMmPerM, fit.p_FixedInTracker_m.y() * kMmPerM,
                        fit.p_FixedInTracker_m.z() * kMmPerM);
  }
  if (!fit.note.empty()) std::cout << "  WARNING: " << fit.note << "\n";

  nlohmann::json out = {{"format", "stepcal-tool/1"}, {"model", a.model}, {"model_id", modelIdHex(*model)},
                        {"touches", a.touches},
                        {"method", method}, {"points", fit.points},
                        {"tcp_in_target_mm", {fit.p_TcpInTip_m.x() * kMmPerM, fit.p_TcpInTip_m.y() * kMmPerM, fit.p_TcpInTip_m.z() * kMmPerM}},
                        {"tcp_covariance_in_target_mm2", matrixJson(fit.covariance_TcpInTip_m2 * kMmPerM * kMmPerM)},
                        {"point_sigma_mm", fit.point_sigma_m * kMmPerM},
                        {"rms_residual_mm", fit.rms_residual_m * kMmPerM},
                        {"least_spread_deg", fit.least_spread_rad * kDegPerRad},
                        {"well_conditioned", fit.well_conditioned}, {"note", fit.note},
                        {"tool_from_target", poseJson(X_TipTcp)}, {"tcp_axes_from", "rotation"}};
  if (axes.measured) printMeasuredAxes(*axes.measured, out);
  std::cout << "for the runtime and stepcal correct (from the target): tool_from target, "
               "tool_x_mm … tool_qz = "
            << toolColumns(X_TipTcp) << "\n";
  if (model->has_flange) {
    const Pose X_FlangeTcp = model->X_TipFlange.inverse() * X_TipTcp;
    const Mat3 R_FlangeTip = X_FlangeTcp.linear() * X_TipTcp.linear().transpose();
    const Mat3 covariance_Flange = R_FlangeTip * fit.covariance_TcpInTip_m2 * R_FlangeTip.transpose();
    printController("the controller's tool data (TCP in the flange)", X_FlangeTcp);
    std::cout << "  1-sigma " << sigmaText(covariance_Flange) << " mm along the flange's x y z\n";
    out["tool_from_flange"] = poseJson(X_FlangeTcp);
    out["tcp_sigma_in_flange_mm"] = {std::sqrt(covariance_Flange(0, 0)) * kMmPerM,
                                     std::sqrt(covariance_Flange(1, 1)) * kMmPerM,
                                     std::sqrt(covariance_Flange(2, 2)) * kMmPerM};
    out["controller"] = controllerJson(X_FlangeTcp);
  } else {
    std::cout << "the model knows no flange (its campaign named no flange_link): no controller "
                 "tool data, only the TCP from the target\n";
  }
  if (!a.out.empty()) {
    const std::string text = out.dump(2) + "\n";
    writeFileAtomically(a.out, text.data(), text.size(), "tool file");
    std::cerr << "wrote " << a.out << "\n";
  }
  return exit_code::kDone;  // a weak fit is a result: it says so, in its note
}

}  // namespace

Subcommand addToolCommand(CLI::App& app) {
  auto args = std::make_shared<ToolArgs>();
  ToolArgs& a = *args;
  CLI::App* cmd = app.add_subcommand(
      "tool", "the TCP with the calibrated robot: from tracker shots at it (joints and x_mm y_mm "
              "z_mm per line) or the four-point method (joints only, one fixed point touched in "
              "4 or more orientations); KUKA, ABB, UR and FANUC tool data with 1-sigma "
              "(docs/cell.md)");
  cmd->add_option("model", a.model, "model file")->required();
  cmd->add_option("touches", a.touches,
                  "touch file (CSV: q1_deg … [, x_mm,y_mm,z_mm]), or a campaign folder of tracker "
                  "shots at the TCP")
      ->required();
  cmd->add_option("--out", a.out, "tool file to write (JSON: the TCP, its covariance, the "
                                  "controller terms; `stepcal frame --tool` and `stepcal correct --tool-file` read it)");
  CLI::Option* rotation =
      cmd->add_option("--rotation", a.rotation,
                      "the TCP's axes in the flange's as a unit quaternion qw qx qy qz (a point "
                      "fixes no orientation; default: measured when every row of a campaign "
                      "gives the TCP's orientation (a 6-D target at the TCP), else 1 0 0 0, the "
                      "flange's axes)")
          ->expected(4);
  cmd->add_option("--payload", a.payload_kg, "the tool's mass during the touches, kg (its weight "
                                             "bends a compliant model; default: the wrench columns, "
                                             "else unloaded)");
  cmd->add_option("--cog", a.cog_mm, "its centre of gravity in the flange frame, mm")->expected(3);
  return {cmd, [args, rotation] {
            args->rotation_given = rotation->count() > 0;
            return runTool(*args);
          }};
}

}  // namespace stepcal::cli
