// stepcal-bench-scale: wall time and peak memory of `stepcal calibrate` and `stepcal diagnose`
// against the number of measured rows (docs/diagnosis.md, "How it scales"). Per size, a dense
// campaign of the simulated IRB4400: a smooth 5-minute path through its pose ranges sampled
// evenly (1.1 kHz at 10⁶ rows; each joint a sine of its own incommensurate frequency, each pose
// at 0, 20 and 40 kg) with a hidden cause (--effect; default a transmission error of joint 2),
// measured as the fit rows by `stepcal simulate --poses`; then `stepcal calibrate` and
// `stepcal diagnose --model` run as the user runs them, each a child process whose wall time and
// peak resident memory (wait4's ru_maxrss) are reported. A size whose diagnosis the previous
// size's memory per row predicts above --max-rss-gb is not run, and says so.
// Prints a markdown table; --json FILE writes every measurement, --html FILE a page with the
// log–log plots, --svg FILE the plots as one image. Exit status 1 when a command fails, 2 on bad options.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "child_process.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/twin/twin.hpp"

namespace fs = std::filesystem;
using stepcal::bench::ChildRun;
using stepcal::bench::runChild;

namespace {

constexpr double kPathSeconds = 300.0;

// The robot's path: 5 minutes, each joint mid + half-range · sin(2π f_j t + φ_j)
// within the IRB4400's pose ranges (a joint kept away from zero, the wrist, on its positive side),
// sampled evenly at rows / 3 poses (1.1 kHz at 10⁶ rows: every size covers the same workspace),
// each pose measured at 0, 20 and 40 kg (a loaded row needs its pose unloaded). poses.csv as
// `stepcal plan` writes it.
void writePath(const fs::path& file, long rows) {
  const std::vector<stepcal::twin::JointSampleRange> ranges = stepcal::twin::defaultIrb4400PoseRanges();
  // Frequencies in Hz, pairwise incommensurate, slow enough for a robot's path: 15–46 cycles.
  const double frequency_hz[] = {0.05, 0.0731, 0.0917, 0.113, 0.1279, 0.1531};
  std::ofstream out(file);
  out << "pose_id,load_kg";
  for (size_t j = 0; j < ranges.size(); ++j) out << ",q" << j + 1 << "_deg";
  out << "\n";
  out.precision(17);
  const long poses = (rows + 2) / 3;
  for (long i = 0; i < rows; ++i) {
    const long pose = i / 3;
    const double t_s = kPathSeconds * static_cast<double>(pose) / static_cast<double>(poses);
    out << "path-" << pose << "," << 20.0 * static_cast<double>(i % 3);
    for (size_t j = 0; j < ranges.size(); ++j) {
      double lower = ranges[j].lower_rad, upper = ranges[j].upper_rad;
      if (ranges[j].min_abs_rad > 0.0) lower = std::max(lower, ranges[j].min_abs_rad);
      const double mid = 0.5 * (lower + upper), half = 0.45 * (upper - lower);
      const double q = mid + half * std::sin(2.0 * stepcal::kPi * frequency_hz[j % 6] * t_s + 0.7 * j);
      out << "," << q / stepcal::kRadPerDeg;
    }
    out << "\n";
  }
}

std::vector<long> parseSizes(const std::string& text) {
  std::vector<long> sizes;
  std::stringstream in(text);
  std::string part;
  while (std::getline(in, part, ',')) {
    size_t used = 0;
    const double value = std::stod(part, &used);
    if (used != part.size() || value < 10 || value > 1e8) throw std::invalid_argument(part);
    sizes.push_back(std::lround(value));
  }
  if (sizes.empty()) throw std::invalid_argument(text);
  return sizes;
}

struct Measured {
  long rows = 0;
  ChildRun simulate, calibrate, diagnose;
  bool skipped = false;
  double predicted_gb = 0.0;
};

// A log–log plot of one quantity against rows for calibrate and diagnose, as inline SVG.
std::string plot(const std::vector<Measured>& all, const char* title, const char* unit,
                 double (*value)(const ChildRun&)) {
  const double W = 460, H = 300, L = 60, R = 20, T = 30, B = 45;
  double x0 = 1e300, x1 = 0, y0 = 1e300, y1 = 0;
  for (const Measured& m : all) {
    if (m.skipped) continue;
    for (const ChildRun* r : {&m.calibrate, &m.diagnose}) {
      x0 = std::min(x0, std::log10(static_cast<double>(m.rows)));
      x1 = std::max(x1, std::log10(static_cast<double>(m.rows)));
      y0 = std::min(y0, std::log10(std::max(value(*r), 1e-3)));
      y1 = std::max(y1, std::log10(std::max(value(*r), 1e-3)));
    }
  }
  x0 = std::floor(x0), x1 = std::max(std::ceil(x1), x0 + 1);
  y0 = std::floor(y0), y1 = std::max(std::ceil(y1), y0 + 1);
  const auto px = [&](double lx) { return L + (lx - x0) / (x1 - x0) * (W - L - R); };
  const auto py = [&](double ly) { return H - B - (ly - y0) / (y1 - y0) * (H - T - B); };
  std::ostringstream s;
  s << "<svg xmlns='http://www.w3.org/2000/svg' width='" << W << "' height='" << H
    << "' font-family='sans-serif' font-size='11'><text x='" << L << "' y='18' font-weight='bold'>"
    << title << "</text>";
  for (double e = x0; e <= x1; ++e) {
    s << "<line x1='" << px(e) << "' y1='" << T << "' x2='" << px(e) << "' y2='" << H - B
      << "' stroke='#ddd'/><text x='" << px(e) << "' y='" << H - B + 15
      << "' text-anchor='middle'>1e" << e << "</text>";
  }
  for (double e = y0; e <= y1; ++e) {
    s << "<line x1='" << L << "' y1='" << py(e) << "' x2='" << W - R << "' y2='" << py(e)
      << "' stroke='#ddd'/><text x='" << L - 5 << "' y='" << py(e) + 4
      << "' text-anchor='end'>1e" << e << "</text>";
  }
  s << "<text x='" << (L + W - R) / 2 << "' y='" << H - 8 << "' text-anchor='middle'>rows</text>"
    << "<text x='14' y='" << (T + H - B) / 2 << "' transform='rotate(-90 14 " << (T + H - B) / 2
    << ")' text-anchor='middle'>" << unit << "</text>";
  const char* colours[] = {"#1f77b4", "#d62728"};
  const char* names[] = {"calibrate", "diagnose"};
  for (int k = 0; k < 2; ++k) {
    s << "<polyline fill='none' stroke='" << colours[k] << "' stroke-width='2' points='";
    for (const Measured& m : all) {
      if (m.skipped) continue;
      const ChildRun& r = k == 0 ? m.calibrate : m.diagnose;
      s << px(std::log10(static_cast<double>(m.rows))) << ","
        << py(std::log10(std::max(value(r), 1e-3))) << " ";
    }
    s << "'/><text x='" << W - R - 70 << "' y='" << T + 14 * (k + 1) << "' fill='" << colours[k]
      << "'>" << names[k] << "</text>";
  }
  s << "</svg>";
  return s.str();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"stepcal-bench-scale: calibrate and diagnose against the number of rows"};
  std::string sizes_text = "1000,3000,10000,30000", work = "out/scale", json_out, html_out, svg_out;
  std::string stepcal = stepcal::bench::stepcalBesideThis();
  double max_rss_gb = 16.0;
  // A hidden cause, so that the search runs its rounds: a second-order transmission error of
  // joint 2 (the size of the docs' shoulder example).
  std::vector<std::string> effects = {
      R"({"name": "transmission_error", "joint": 2, "harmonic": 2, "sin_rad": 4e-5, "cos_rad": -2e-5})"};
  app.add_option("--rows", sizes_text, "campaign sizes in fit rows, e.g. 1e3,1e4,1e5")
      ->capture_default_str();
  app.add_option("--out", work, "working folder (a campaign per size)")->capture_default_str();
  app.add_option("--max-rss-gb", max_rss_gb,
                 "do not run a diagnosis predicted to need more peak memory than this, GB")
      ->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--effect", effects, "hidden mechanism as `stepcal simulate --effect` takes it, repeatable")
      ->capture_default_str();
  app.add_option("--json", json_out, "file for every measurement");
  app.add_option("--html", html_out, "page with the log-log plots");
  app.add_option("--svg", svg_out, "the two log-log plots side by side as one SVG image");
  app.add_option("--stepcal", stepcal, "the stepcal command to run")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  std::vector<long> sizes;
  try {
    sizes = parseSizes(sizes_text);
  } catch (const std::exception&) {
    std::cerr << "stepcal-bench-scale: error: --rows '" << sizes_text
              << "'; expected sizes from 10 to 1e8 separated by commas, such as 1e3,1e4,1e5\n";
    return 2;
  }
  if (!stepcal::bench::stepcalIsExecutable("stepcal-bench-scale", stepcal)) return 2;

  std::vector<Measured> all;
  double diagnose_mb_per_row = 0.0;
  bool failed = false;
  std::printf("| rows | simulate s | calibrate s | calibrate MB | diagnose s | diagnose MB | diagnose ms/row | diagnose kB/row |\n");
  std::printf("|---|---|---|---|---|---|---|---|\n");
  for (long rows : sizes) {
    Measured m;
    m.rows = rows;
    m.predicted_gb = diagnose_mb_per_row * static_cast<double>(rows) / 1024.0;
    if (m.predicted_gb > max_rss_gb) {
      m.skipped = true;
      std::printf("| %ld | not run: the diagnosis would need about %.1f GB at %.0f kB per row (--max-rss-gb %.0f) | | | | | | |\n",
                  rows, m.predicted_gb, diagnose_mb_per_row * 1024.0, max_rss_gb);
      all.push_back(m);
      continue;
    }
    const fs::path dir = fs::path(work) / std::to_string(rows);
    fs::create_directories(dir);
    writePath(dir / "poses.csv", rows);
    const std::string campaign = (dir / "campaign").string(), poe = (dir / "poe.stepcal").string();
    std::vector<std::string> simulate = {stepcal, "simulate", "--seed", "1", "--poses",
                                         (dir / "poses.csv").string(), "--out", campaign};
    for (const std::string& e : effects) simulate.insert(simulate.end(), {"--effect", e});
    m.simulate = runChild(simulate, dir / "simulate.out", dir / "simulate.err");
    if (m.simulate.status == 0) {
      m.calibrate = runChild({stepcal, "calibrate", campaign, "--out", poe}, dir / "calibrate.out",
                        dir / "calibrate.err");
    }
    if (m.simulate.status == 0 && m.calibrate.status == 0) {
      m.diagnose = runChild({stepcal, "diagnose", campaign, "--model", poe, "--json", "--out",
                        (dir / "extended.stepcal").string()},
                       dir / "diagnose.json", dir / "diagnose.err");
    }
    const int status = m.simulate.status ? m.simulate.status
                       : m.calibrate.status ? m.calibrate.status : m.diagnose.status;
    if (status != 0) {
      std::printf("| %ld | failed with status %d (see %s) | | | | | | |\n", rows, status,
                  dir.c_str());
      failed = true;
      all.push_back(m);
      continue;
    }
    diagnose_mb_per_row = m.diagnose.max_rss_mb / static_cast<double>(rows);
    std::printf("| %ld | %.1f | %.1f | %.0f | %.1f | %.0f | %.2f | %.0f |\n", rows, m.simulate.wall_s,
                m.calibrate.wall_s, m.calibrate.max_rss_mb, m.diagnose.wall_s,
                m.diagnose.max_rss_mb, 1e3 * m.diagnose.wall_s / static_cast<double>(rows),
                1024.0 * diagnose_mb_per_row);
    std::fflush(stdout);
    all.push_back(m);
  }

  if (!json_out.empty()) {
    nlohmann::json out = nlohmann::json::array();
    for (const Measured& m : all) {
      nlohmann::json j{{"rows", m.rows}, {"skipped", m.skipped}};
      if (m.skipped) j["predicted_diagnose_gb"] = m.predicted_gb;
      for (const auto& [name, r] : {std::pair<const char*, const ChildRun&>{"simulate", m.simulate},
                                    {"calibrate", m.calibrate},
                                    {"diagnose", m.diagnose}}) {
        if (!m.skipped) j[name] = {{"status", r.status}, {"wall_s", r.wall_s}, {"max_rss_mb", r.max_rss_mb}};
      }
      out.push_back(j);
    }
    std::ofstream(json_out) << out.dump(2) << "\n";
  }
  const std::string time_plot = plot(all, "wall time", "s", [](const ChildRun& r) { return r.wall_s; });
  const std::string memory_plot =
      plot(all, "peak resident memory", "MB", [](const ChildRun& r) { return r.max_rss_mb; });
  if (!html_out.empty()) {
    std::ofstream html(html_out);
    html << "<!doctype html><html><head><meta charset='utf-8'><title>stepcal: how calibrate and "
            "diagnose scale</title></head><body><h1>calibrate and diagnose against the rows</h1>"
            "<p>Dense campaigns of the simulated IRB4400 (a 5-minute path sampled evenly, three "
            "loads), stepcal-bench-scale.</p>"
         << time_plot << memory_plot << "</body></html>\n";
  }
  if (!svg_out.empty()) {
    std::ofstream svg(svg_out);
    svg << "<svg xmlns='http://www.w3.org/2000/svg' width='920' height='300'><rect width='920' "
           "height='300' fill='white'/><g>"
        << time_plot << "</g><g transform='translate(460,0)'>" << memory_plot << "</g></svg>\n";
  }
  return failed ? 1 : 0;
}
