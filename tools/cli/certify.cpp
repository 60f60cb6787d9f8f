// `stepcal certify`: the pose characteristics of ISO 9283 (trainer/iso9283.hpp) of a campaign,
// as commanded and as corrected by a model file, as text, JSON and an HTML certificate.
#include <cstdio>
#include <fstream>
#include <iostream>
#include <iterator>
#include <memory>
#include <string>
#include <vector>

#include "common.hpp"
#include "stepcal/common/campaign.hpp"
#include "stepcal/common/error.hpp"
#include "stepcal/common/model_file.hpp"
#include "stepcal/common/model_robot.hpp"
#include "stepcal/report/certificate.hpp"
#include "stepcal/trainer/iso9283.hpp"
#include "subcommands.hpp"

namespace stepcal::cli {
namespace {

struct CertifyArgs {
  std::string model, campaign;
  bool json = false;
  bool refit_frames = false;
  std::string set;  ///< empty: every row
  std::string html_out;
  double same_pose_mm = 0.2;
};

/// The model file's own checksum as 8 hex digits: the CRC-32 of everything before its last 4
/// bytes, which hold it (readModelFile has checked the file, so it has them).
std::string modelChecksum(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  const std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                   std::istreambuf_iterator<char>());
  constexpr size_t kCrcBytes = 4;
  if (bytes.size() < kCrcBytes) throw InputError("the model file changed while being read", path);
  char hex[16];
  std::snprintf(hex, sizeof hex, "%08x", crc32Ieee(bytes.data(), bytes.size() - kCrcBytes));
  return hex;
}

std::optional<RowSet> rowSet(const std::string& name) {
  if (name.empty()) return std::nullopt;
  for (const RowSet set : {RowSet::kGeometry, RowSet::kStiffness, RowSet::kResidual,
                           RowSet::kValidation}) {
    if (name == toString(set)) return set;
  }
  throw InputError("--set '" + name +
                   "'; expected geometry, stiffness, residual or validation (hint: validation "
                   "for the rows the model was not fitted on)");
}

void runCertify(const CertifyArgs& a) {
  const CalibratedModel model = readModelFile(a.model);
  const Campaign campaign = readCampaign(a.campaign);
  requireCampaignOfModelRobot(model, campaign, a.model);
  trainer::IsoCertifyOptions options;
  options.refit_frames = a.refit_frames;
  options.set = rowSet(a.set);
  if (!(a.same_pose_mm > 0.0 && a.same_pose_mm < 1e3)) {
    throw InputError("--same-pose-mm " + std::to_string(a.same_pose_mm) +
                     "; expected a distance > 0 mm (hint: the largest difference between the "
                     "commanded positions of one pose's cycles, 0.2)");
  }
  options.same_pose_position_m = a.same_pose_mm * 1e-3;
  trainer::IsoCertificate certificate = trainer::certifyIso9283(model, campaign, options);
  certificate.model_path = a.model;
  certificate.model_crc32 = modelChecksum(a.model);
  if (!a.html_out.empty()) {
    writeReport(a.html_out, report::certificateHtml(certificate));
    std::cerr << "wrote " << a.html_out << "\n";
  }
  if (a.json) {
    std::cout << report::certificateJson(certificate).dump(2) << "\n";
  } else {
    std::cout << report::formatCertificate(certificate);
  }
}

}  // namespace

Subcommand addCertifyCommand(CLI::App& app) {
  auto args = std::make_shared<CertifyArgs>();
  CertifyArgs& a = *args;
  CLI::App* certify = app.add_subcommand(
      "certify", "the pose characteristics of ISO 9283 (AP, RP, vAP, AD, RD) per load, as "
                 "commanded and as corrected by a model file, from a campaign (e.g. of stepcal "
                 "plan --iso9283)");
  certify->add_option("model", a.model, "model file")->required();
  certify->add_option("campaign", a.campaign,
                      "campaign folder: the rows of a stepcal plan --iso9283 where it has any, "
                      "else every row, grouped into poses by load, commanded pose "
                      "(--same-pose-mm, 0.5°) and joints (0.01 rad)")
      ->required();
  certify->add_option("--set", a.set,
                      "only the rows of this set (geometry, stiffness, residual, validation)");
  certify->add_flag("--refit-frames", a.refit_frames,
                    "place the commanded poses by registering the nominal robot on these rows and "
                    "fit the model's tracker and tool frames on them (a campaign measured with "
                    "the tracker moved; the fit takes up part of the accuracy it is judged on)");
  certify
      ->add_option("--same-pose-mm", a.same_pose_mm,
                   "rows whose commanded positions (the nominal tip at their joints) lie this "
                   "close, with orientations within 0.5° and joints within 0.01 rad, are cycles "
                   "of one pose, mm")
      ->capture_default_str();
  certify->add_flag("--json", a.json, "print the certificate as JSON (SI units)");
  certify->add_option("--html", a.html_out, "self-contained HTML certificate to write");
  return {certify, [args] { runCertify(*args); }};
}

}  // namespace stepcal::cli
