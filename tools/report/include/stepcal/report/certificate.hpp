// ISO 9283 renderings: the test layout of `stepcal plan --iso9283`, and the certificate of
// `stepcal certify` as text, JSON and a self-contained HTML page (mm and degrees).
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "stepcal/trainer/iso9283.hpp"
#include "stepcal/trainer/iso9283_plan.hpp"

namespace stepcal::report {

/// The cube, its poses and joints, the cycles, approach directions and loads, in words.
std::string formatIsoPlan(const trainer::Iso9283Plan& plan);

/// Per load and method: AP, RP, vAP, AD, RD (mm, deg), with what each means; poses listed when
/// at most 12.
std::string formatCertificate(const trainer::IsoCertificate& certificate);

/// Everything of the certificate, SI units in the key names; a figure the rows cannot give is
/// null with its reason beside ("…_not_measurable").
nlohmann::json certificateJson(const trainer::IsoCertificate& certificate);

/// One self-contained page (html/page.hpp): the robot, model checksum, campaign, temperatures,
/// the figures per load with what each means, and charts of AP and RP per pose and of each
/// pose's cycles around their barycentre.
std::string certificateHtml(const trainer::IsoCertificate& certificate);

}  // namespace stepcal::report
