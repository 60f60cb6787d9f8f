#include "stepcal/report/certificate.hpp"

#include <sstream>

#include "stepcal/common/lie.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/report/text_format.hpp"

namespace stepcal::report {
namespace {

constexpr double kMmPerM = 1e3;
constexpr size_t kPosesListed = 12;

std::string figureText(const trainer::IsoFigure& figure) {
  return figure.value ? format("%.3f mm", *figure.value * kMmPerM)
                      : "not measurable from these rows (" + figure.not_measurable + ")";
}

std::string anglesText(const std::optional<Vec3>& angles_rad) {
  if (!angles_rad) return "-";
  const Vec3 deg = *angles_rad / kRadPerDeg;
  return format("%.4f/%.4f/%.4f", deg.x(), deg.y(), deg.z());
}

nlohmann::json figureJson(const trainer::IsoFigure& figure) {
  return figure.value ? nlohmann::json(*figure.value) : nlohmann::json(nullptr);
}

void putFigure(nlohmann::json& j, const std::string& key, const trainer::IsoFigure& figure) {
  j[key + "_m"] = figureJson(figure);
  if (!figure.value) j[key + "_not_measurable"] = figure.not_measurable;
}

nlohmann::json anglesJson(const std::optional<Vec3>& angles_rad) {
  return angles_rad ? nlohmann::json{angles_rad->x(), angles_rad->y(), angles_rad->z()}
                    : nlohmann::json(nullptr);
}

nlohmann::json poseJson(const trainer::IsoPoseFigures& pose) {
  nlohmann::json j;
  j["pose"] = pose.label;
  j["first_pose_id"] = pose.first_pose_id;
  j["commanded_in_base_m"] = {pose.p_CommandedInBase_m.x(), pose.p_CommandedInBase_m.y(),
                              pose.p_CommandedInBase_m.z()};
  j["cycles"] = pose.cycles;
  j["barycentre_deviation_base_m"] = {pose.mean_deviation_Base_m.x(),
                                      pose.mean_deviation_Base_m.y(),
                                      pose.mean_deviation_Base_m.z()};
  putFigure(j, "ap_position", pose.ap_position);
  j["ap_orientation_abc_rad"] = anglesJson(pose.ap_orientation_rad);
  putFigure(j, "rp_position", pose.rp_position);
  j["rp_orientation_abc_rad"] = anglesJson(pose.rp_orientation_rad);
  putFigure(j, "vap_position", pose.vap_position);
  j["vap_orientation_abc_rad"] = anglesJson(pose.vap_orientation_rad);
  return j;
}

void methodText(const trainer::IsoMethodFigures& m, std::ostringstream& out) {
  out << "  " << m.method << ":\n"
      << "    AP_P (largest over the poses)  " << figureText(m.ap_position_max) << "\n"
      << "    AP_P (median of the poses)     " << figureText(m.ap_position_median) << "\n"
      << "    RP_l (largest over the poses)  " << figureText(m.rp_position_max) << "\n"
      << "    RP_l (median of the poses)     " << figureText(m.rp_position_median) << "\n"
      << "    RP_l (cycles pooled)           " << figureText(m.rp_position_pooled) << "\n"
      << "    vAP_P (largest)                " << figureText(m.vap_position_max) << "\n"
      << "    AD_P (P2–P4, " << m.distance_cycles << " cycles)        "
      << figureText(m.ad_position) << "\n"
      << "    RD_P                           " << figureText(m.rd_position) << "\n";
  if (m.poses.size() > kPosesListed) {
    out << "    (" << m.poses.size() << " poses: per pose in --json and --html)\n";
    return;
  }
  out << format("    %-7s %6s %10s %10s %10s  %-26s %s\n", "pose", "cycles", "AP_P mm", "RP_l mm",
                "vAP_P mm", "AP_a/b/c deg", "RP_a/b/c deg");
  for (const trainer::IsoPoseFigures& p : m.poses) {
    auto mm = [](const trainer::IsoFigure& f) {
      return f.value ? format("%.3f", *f.value * kMmPerM) : std::string("n/m");
    };
    out << format("    %-7s %6d %10s %10s %10s  %-26s %s\n", p.label.c_str(), p.cycles,
                  mm(p.ap_position).c_str(), mm(p.rp_position).c_str(),
                  mm(p.vap_position).c_str(), anglesText(p.ap_orientation_rad).c_str(),
                  anglesText(p.rp_orientation_rad).c_str());
  }
}

}  // namespace

std::string formatIsoPlan(const trainer::Iso9283Plan& plan) {
  std::ostringstream out;
  const Vec3& c = plan.p_CentreInBase_m;
  out << "ISO 9283 test (pose characteristics)\n"
      << format("  cube: edge %.1f mm, edges along base_link's axes, centre (%.1f, %.1f, %.1f) mm "
                "in base_link; the largest reached with one tool orientation at its 8 corners and "
                "5 poses (best of %d drawn configurations, %d with a link below the floor)\n",
                plan.edge_m * kMmPerM, c.x() * kMmPerM, c.y() * kMmPerM, c.z() * kMmPerM,
                plan.candidates_drawn, plan.candidates_below_floor)
      << "  test plane: the cube's diagonal plane through its two edges along base y "
         "(x - x_c = z - z_c); P1 at its centre, P2-P5 on its diagonals at 10 % of the diagonal's "
         "length from its corners\n";
  const Vec3 rpy = lie::rpyFromRotation(plan.R_BaseTip) / kRadPerDeg;
  out << format("  tool orientation at every pose: roll, pitch, yaw %.1f, %.1f, %.1f deg "
                "(URDF's: R = Rz(yaw) Ry(pitch) Rx(roll) in base_link)\n",
                rpy.x(), rpy.y(), rpy.z());
  out << "  pose  position in base_link (mm)          joints (deg)\n";
  for (size_t k = 0; k < plan.p_PoseInBase_m.size(); ++k) {
    const Vec3& p = plan.p_PoseInBase_m[k];
    out << format("  P%zu    (%8.1f, %8.1f, %8.1f)      ", k + 1, p.x() * kMmPerM,
                  p.y() * kMmPerM, p.z() * kMmPerM);
    for (int j = 0; j < plan.q_pose_rad[k].size(); ++j) {
      out << format(" %7.2f", plan.q_pose_rad[k](j) / kRadPerDeg);
    }
    out << "\n";
  }
  out << format("  cycles: %d of P1 -> P2 -> P3 -> P4 -> P5 (pose accuracy AP and repeatability "
                "RP; distance accuracy AD and repeatability RD between P2 and P4)\n",
                plan.cycles)
      << format("  approach directions: P1, P2, P4 each approached moving along +x, +y and +z of "
                "base_link from a via-point %.0f mm back, %d cycles each (multi-directional "
                "variation vAP); the pose_id names the direction (iso-P2-y-c07)\n",
                trainer::kIsoApproachDistance_m * kMmPerM, plan.cycles);
  out << "  loads:";
  for (const double load_kg : plan.loads_kg) out << format(" %g kg", load_kg);
  out << (plan.loads_kg.size() > 1 ? " (unloaded, 10 % of rated, rated)\n"
                                   : " (unloaded only: give --rated-load-kg for the standard's "
                                     "rated and 10 % loads)\n");
  out << format("  rows: %zu; not checked: the tracker's line of sight, the cube's edges between "
                "its corners\n", plan.rows.size());
  return out.str();
}

std::string formatCertificate(const trainer::IsoCertificate& c) {
  std::ostringstream out;
  out << "ISO 9283 pose characteristics of " << (c.robot_name.empty() ? "the robot" : c.robot_name)
      << "\n  campaign " << c.campaign_directory << " (hash " << c.campaign_hash << "), "
      << c.rows_used << " rows"
      << (c.iso_plan_rows ? " of a stepcal plan --iso9283" : "")
      << (c.rows_left_out > 0 ? ", " + std::to_string(c.rows_left_out) + " left out" : "")
      << "\n  model " << c.model_path << " (CRC-32 " << c.model_crc32 << "), corrected by "
      << c.corrected_method << (c.frames_refit ? "; tracker and tool frames fitted on these rows" : "")
      << "\n";
  if (c.temperature_min_c) {
    out << format("  temperature %.2f–%.2f °C\n", *c.temperature_min_c, *c.temperature_max_c);
  }
  out << format("  tracker noise %.3f mm per axis (1-σ, as the campaign states)\n",
                c.tracker_position_sigma_m * kMmPerM);
  out << "  commanded: the nominal robot at the rows' joints (what the controller aims at, "
         "uncorrected); corrected: attained - the model's prediction (where the corrected robot "
         "lands about its target)\n"
         "  AP_P distance of the cycles' barycentre from the commanded position; RP_l = l̄ + 3 S_l "
         "of the attained positions' distances from their barycentre (both methods alike); "
         "vAP_P largest distance between the barycentres of the approach directions; AD_P mean "
         "attained minus commanded distance P2-P4; RD_P 3 S of it; AP_a/b/c and RP_a/b/c about base x/y/z\n";
  for (const trainer::IsoLoadFigures& load : c.loads) {
    out << format("load %g kg: %d rows, %d poses measured more than once\n", load.load_kg,
                  load.rows, load.poses_with_cycles);
    for (const trainer::IsoMethodFigures& m : load.methods) methodText(m, out);
  }
  return out.str();
}

nlohmann::json certificateJson(const trainer::IsoCertificate& c) {
  nlohmann::json j;
  j["format"] = "stepcal-iso9283-certificate/1";
  j["robot"] = c.robot_name;
  j["campaign"] = c.campaign_directory;
  j["campaign_hash"] = c.campaign_hash;
  j["model"] = c.model_path;
  j["model_crc32"] = c.model_crc32;
  j["corrected_method"] = c.corrected_method;
  j["iso_plan_rows"] = c.iso_plan_rows;
  j["rows_used"] = c.rows_used;
  j["rows_left_out"] = c.rows_left_out;
  j["frames_refit"] = c.frames_refit;
  j["temperature_min_c"] = c.temperature_min_c ? nlohmann::json(*c.temperature_min_c) : nullptr;
  j["temperature_max_c"] = c.temperature_max_c ? nlohmann::json(*c.temperature_max_c) : nullptr;
  j["tracker_position_sigma_m"] = c.tracker_position_sigma_m;
  j["loads"] = nlohmann::json::array();
  for (const trainer::IsoLoadFigures& load : c.loads) {
    nlohmann::json l;
    l["load_kg"] = load.load_kg;
    l["rows"] = load.rows;
    l["poses_with_cycles"] = load.poses_with_cycles;
    l["methods"] = nlohmann::json::array();
    for (const trainer::IsoMethodFigures& m : load.methods) {
      nlohmann::json mj;
      mj["method"] = m.method;
      putFigure(mj, "ap_position_max", m.ap_position_max);
      putFigure(mj, "ap_position_median", m.ap_position_median);
      putFigure(mj, "rp_position_max", m.rp_position_max);
      putFigure(mj, "rp_position_median", m.rp_position_median);
      putFigure(mj, "rp_position_pooled", m.rp_position_pooled);
      putFigure(mj, "vap_position_max", m.vap_position_max);
      putFigure(mj, "ad_position", m.ad_position);
      putFigure(mj, "rd_position", m.rd_position);
      mj["distance_cycles"] = m.distance_cycles;
      mj["poses"] = nlohmann::json::array();
      for (const trainer::IsoPoseFigures& p : m.poses) mj["poses"].push_back(poseJson(p));
      l["methods"].push_back(mj);
    }
    j["loads"].push_back(l);
  }
  return j;
}

}  // namespace stepcal::report
