// stepcal-diagnose-stress: the diagnosis on campaigns it was not tuned to. Per seed, a random mix
// of 0–3 of the twin's mechanisms (twin::drawMechanismMix: every kind, the torque-driven ones on
// a joint another loads too, self weight from a few kilograms up) is simulated into the paper's
// campaign by `stepcal simulate`, diagnosed by `stepcal diagnose --json` as a user would run it
// (a separate process: an abort is an outcome, not the end of the run), and judged:
//   abort     the diagnosis ended by a signal or with a status other than 0;
//   named     the causes named are the hidden ones: each hidden mechanism named (a torque-driven
//             one by any torque–deflection mechanism of its joint: backlash, nonlinear stiffness
//             and a torsion curve are one curve of the joint's torque), nothing else; a hidden
//             one the diagnosis says it cannot test on these rows counts neither way;
//   worst     the extended model's largest mean position error over the validation loads,
//             against the tracker-noise floor;
//   never worse  the model `diagnose --out` writes (its GPR where one is taken) at no validation
//             load worse than the paper's: step 1 on the unloaded rows (within 1.1x), its three
//             steps on every loaded one; a load within 1.2x the floor is never worse.
// Prints one line per seed and a summary table; --json FILE writes every seed's outcome. Exit
// status 1 on any abort, and with --strict also on a wrong named set or a load above 1.5× the
// floor; 2 on bad options.
//
// --foreign hides load effects outside the catalogue instead (twin::drawForeignMix, issue 43):
// a bearing_tilt alone, an angle_dependent_stiffness alone, either beside one catalogued
// mechanism, or both, payloads in time blocks as in the paper. Judged: a drift named
// (registration_drift, joint_zero_drift: none is hidden), a cause named that is not in the data
// (as above), a hidden catalogued one missed, a bearing_tilt of joint j not named as an
// off_axis_compliance of joint j (an angle_dependent_stiffness has no catalogue kind to be named
// as), the worst load; and what the verdict says is left (unexplained_trend, and `unexplained`
// where the diagnosis writes it). The summary has a row per design. --load-order mixed measures
// every campaign's fit rows shuffled (stepcal simulate --load-order), so that load and time order
// do not correlate.
#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "child_process.hpp"
#include "stepcal/twin/draws.hpp"

namespace fs = std::filesystem;
using stepcal::MechanismKind;
using stepcal::twin::DrawnMechanism;


namespace {

constexpr double kFloorLimit = 1.5;

// Runs argv with stdout and stderr to files; the shell-style status (128 + signal when killed).
int run(const std::vector<std::string>& argv, const fs::path& out, const fs::path& err) {
  return stepcal::bench::runChild(argv, out, err).status;
}

bool torqueDriven(const std::string& name) {
  return name == "backlash" || name == "nonlinear_stiffness" || name == "torsion_curve";
}

// What a diagnosis names, as the JSON has it: name, joint and coupling joints (1-based).
struct Named {
  std::string name;
  int joint = 0;
  std::vector<int> joints;
};

bool matches(const DrawnMechanism& h, const Named& n) {
  const std::string hidden = h.effect.at("name");
  if (torqueDriven(hidden)) return torqueDriven(n.name) && n.joint == h.joint + 1;
  if (hidden != n.name) return false;
  if (hidden == "transmission_error") return n.joint == h.joint + 1;
  if (hidden == "joint_coupling") {
    return n.joints == std::vector<int>{h.source_joint + 1, h.joint + 1};
  }
  return true;
}

// The diagnosis's name for what cannot be tested, e.g. "backlash (joint 2)".
std::string untestableName(const DrawnMechanism& h) {
  const std::string name = h.effect.at("name");
  if (h.joint < 0 || name == "joint_coupling") return name;
  return name + " (joint " + std::to_string(h.joint + 1) + ")";
}

bool isDrift(const std::string& name) {
  return name == "registration_drift" || name == "joint_zero_drift";
}

// A foreign effect's name as the table shows it, e.g. "bearing_tilt (joint 1)".
std::string foreignName(const nlohmann::json& effect) {
  return effect.at("name").get<std::string>() + " (joint " +
         std::to_string(effect.at("joint").get<int>()) + ")";
}

// The catalogue kind that describes a foreign effect, when there is one: a bearing tilt is an
// off-axis compliance of its joint (the kind issue 43 adds); a stiffness varying with the angle
// has none.
bool describes(const nlohmann::json& foreign, const Named& n) {
  return foreign.at("name") == "bearing_tilt" && n.name == "off_axis_compliance" &&
         n.joint == foreign.at("joint").get<int>();
}

struct Outcome {
  uint64_t seed = 0;
  std::string design;                  // --foreign: drawForeignMix's design
  std::vector<nlohmann::json> foreign;  // --foreign: the effects outside the catalogue
  std::vector<DrawnMechanism> hidden;   // the catalogued ones
  int status = 0;           // of stepcal diagnose
  std::string error;        // its last stderr line when it failed
  std::vector<std::string> named, missing, extra, untestable;
  std::vector<std::string> foreign_found, foreign_missing;  // bearing tilts named or not
  int drifts_named = 0;         // of extra, the drifts
  std::string unexplained_trend;  // the verdict's text, "" when none
  std::string unexplained;        // the diagnosis's `unexplained` field, compact JSON, if any
  double worst_over_floor = 0.0;
  std::vector<std::string> worse_loads;  // where the written model is worse than the paper's
  double seconds = 0.0;
  bool abort() const { return status != 0; }
  // A cause named beside the drifts that is not in the data.
  bool otherExtra() const { return static_cast<int>(extra.size()) > drifts_named; }
  bool rightSet() const {
    return !abort() && missing.empty() && extra.empty() && foreign_missing.empty();
  }
  bool atFloor() const { return !abort() && worst_over_floor <= kFloorLimit; }
  bool neverWorse() const { return !abort() && worse_loads.empty(); }
};

std::string describe(const Named& n) {
  if (!n.joints.empty()) return n.name + " (" + std::to_string(n.joints[0]) + "->" + std::to_string(n.joints[1]) + ")";
  return n.joint > 0 ? n.name + " (joint " + std::to_string(n.joint) + ")" : n.name;
}

std::string lastLine(const fs::path& file) {
  std::ifstream in(file);
  std::string line, last;
  while (std::getline(in, line)) {
    if (!line.empty()) last = line;
  }
  return last;
}

// Issue 43's "never worse than the model under it, at any load": the model `diagnose --out` writes
// (with its GPR where one is taken) against the paper's step 1 on the unloaded validation rows and
// its three steps on every loaded load, the extrapolated one included. The unloaded margin as in
// tests/test_diagnose_load_effects.cpp: the geometry identified from fewer rows may lose a little
// to noise. A load within kAtFloor of the tracker-noise floor is worse than nothing: the mean
// error of 50 rows at the floor scatters by 5.9 % (a 3-D Gaussian's length: std 0.42 of its
// mean, over √50), so 1.2 is 3.4 of that; there two models differ by the rows' noise alone (a
// clean campaign's 55 kg rows: 0.0181 against 0.0179 mm, 1.13x the floor).
constexpr double kUnloadedMargin = 1.1;
constexpr double kAtFloor = 1.2;

void judgeNeverWorse(const nlohmann::json& gain, double floor_mm, Outcome& o) {
  for (const nlohmann::json& g : gain) {
    const char* layer = g.contains("after_gpr_mean_position_mm") && !g.at("after_gpr_mean_position_mm").is_null()
                            ? "after_gpr_mean_position_mm" : "after_mean_position_mm";
    if (!g.contains(layer) || g.at(layer).is_null()) continue;
    const double load_kg = g.at("load_kg"), written_mm = g.at(layer);
    const bool unloaded = load_kg == 0.0;
    const char* reference = unloaded ? "before_mean_position_mm" : "gpr_mean_position_mm";
    if (!g.contains(reference) || g.at(reference).is_null()) continue;
    const double reference_mm = g.at(reference);
    if (written_mm > (unloaded ? kUnloadedMargin : 1.0) * reference_mm && written_mm > kAtFloor * floor_mm) {
      char text[96];
      std::snprintf(text, sizeof text, "%g kg %.4f > %s %.4f", load_kg, written_mm,
                    unloaded ? "step 1" : "paper", reference_mm);
      o.worse_loads.push_back(text);
    }
  }
}

// The named set against the hidden one, and the worst load against the floor.
void judge(const nlohmann::json& d, Outcome& o) {
  std::vector<Named> named;
  for (const nlohmann::json& e : d.at("effects")) {
    Named n;
    n.name = e.at("name");
    if (!e.at("joint").is_null()) n.joint = e.at("joint");
    if (!e.at("joints").is_null()) n.joints = e.at("joints").get<std::vector<int>>();
    named.push_back(n);
    o.named.push_back(describe(n));
  }
  std::vector<std::string> untestable;
  for (const nlohmann::json& u : d.at("untestable")) untestable.push_back(u.at("name"));
  std::vector<bool> used(named.size(), false);
  for (const nlohmann::json& f : o.foreign) {
    bool found = false;
    for (size_t k = 0; k < named.size(); ++k) {
      if (describes(f, named[k])) found = used[k] = true;
    }
    if (found) {
      o.foreign_found.push_back(foreignName(f));
    } else if (f.at("name") == "bearing_tilt") {
      o.foreign_missing.push_back(foreignName(f));
    }
  }
  for (const DrawnMechanism& h : o.hidden) {
    bool found = false;
    for (size_t k = 0; k < named.size(); ++k) {
      if (matches(h, named[k])) found = used[k] = true;
    }
    if (found) continue;
    const std::string u = untestableName(h);
    if (std::find(untestable.begin(), untestable.end(), u) != untestable.end()) {
      o.untestable.push_back(u);
    } else {
      o.missing.push_back(u);
    }
  }
  for (size_t k = 0; k < named.size(); ++k) {
    if (used[k]) continue;
    o.extra.push_back(describe(named[k]));
    o.drifts_named += isDrift(named[k].name);
  }
  const double floor = d.at("noise_floor_position_mm");
  for (const nlohmann::json& g : d.at("gain")) {
    if (g.contains("after_mean_position_mm") && !g.at("after_mean_position_mm").is_null()) {
      o.worst_over_floor = std::max(o.worst_over_floor, g.at("after_mean_position_mm").get<double>() / floor);
    }
  }
  judgeNeverWorse(d.at("gain"), floor, o);
}

// Reads what the diagnosis says is left: unexplained_trend, and `unexplained` when present.
void readUnexplained(const nlohmann::json& d, Outcome& o) {
  if (d.contains("unexplained_trend") && d.at("unexplained_trend").is_string()) {
    o.unexplained_trend = d.at("unexplained_trend");
  }
  if (d.contains("unexplained") && !d.at("unexplained").is_null()) {
    o.unexplained = d.at("unexplained").dump();
  }
}

// How a seed is run: the mixes drawn and the campaign's load order.
struct RunOptions {
  std::string stepcal;
  fs::path work;
  bool foreign = false;
  std::string load_order = "blocks";  // stepcal simulate --load-order
};

Outcome diagnoseSeed(uint64_t seed, const RunOptions& run_options) {
  const std::string& stepcal = run_options.stepcal;
  const fs::path& work = run_options.work;
  Outcome o;
  o.seed = seed;
  if (run_options.foreign) {
    stepcal::twin::ForeignMix mix = stepcal::twin::drawForeignMix(seed);
    o.design = mix.design;
    o.foreign = std::move(mix.foreign);
    o.hidden = std::move(mix.catalogued);
  } else {
    o.hidden = stepcal::twin::drawMechanismMix(seed);
  }
  const fs::path dir = work / ("seed-" + std::to_string(seed));
  fs::remove_all(dir);
  fs::create_directories(work);
  std::vector<std::string> simulate = {stepcal, "simulate", "--seed", std::to_string(seed), "--out",
                                       dir.string()};
  if (run_options.load_order != "blocks") {
    simulate.insert(simulate.end(), {"--load-order", run_options.load_order});
  }
  for (const DrawnMechanism& h : o.hidden) {
    simulate.push_back("--effect");
    simulate.push_back(h.effect.dump());
  }
  for (const nlohmann::json& f : o.foreign) {
    simulate.push_back("--effect");
    simulate.push_back(f.dump());
  }
  const fs::path log = work / ("seed-" + std::to_string(seed) + ".simulate.log");
  if (const int status = run(simulate, log, log); status != 0) {
    o.status = status;
    o.error = "simulate: " + lastLine(log);
    return o;
  }
  const auto start = std::chrono::steady_clock::now();
  o.status = run({stepcal, "diagnose", dir.string(), "--json"}, dir / "diagnose.json",
                 dir / "diagnose.err");
  o.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (o.status != 0) {
    o.error = lastLine(dir / "diagnose.err");
    return o;
  }
  nlohmann::json d;
  try {
    std::ifstream(dir / "diagnose.json") >> d;
  } catch (const nlohmann::json::exception& e) {
    o.status = 254;
    o.error = std::string("unreadable diagnose.json: ") + e.what();
    return o;
  }
  judge(d, o);
  readUnexplained(d, o);
  return o;
}

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const std::string& x : v) s += (s.empty() ? "" : ", ") + x;
  return s.empty() ? "-" : s;
}

nlohmann::json toJson(const Outcome& o) {
  nlohmann::json hidden = nlohmann::json::array();
  for (const DrawnMechanism& h : o.hidden) hidden.push_back(h.effect);
  nlohmann::json j = {{"seed", o.seed},          {"hidden", hidden},       {"status", o.status},
                      {"error", o.error},        {"named", o.named},       {"missing", o.missing},
                      {"extra", o.extra},        {"untestable", o.untestable},
                      {"worst_over_floor", o.worst_over_floor},            {"seconds", o.seconds},
                      {"right_set", o.rightSet()}, {"at_floor", o.atFloor()},
                      {"never_worse", o.neverWorse()}, {"worse_loads", o.worse_loads}};
  if (!o.design.empty()) {
    j["design"] = o.design;
    j["foreign"] = o.foreign;
    j["foreign_found"] = o.foreign_found;
    j["foreign_missing"] = o.foreign_missing;
    j["drift_named"] = o.drifts_named > 0;
    j["unexplained_trend"] = o.unexplained_trend;
    j["unexplained"] = o.unexplained.empty() ? nlohmann::json(nullptr) : nlohmann::json::parse(o.unexplained);
  }
  return j;
}

const char* verdict(const Outcome& o) {
  if (o.abort()) return "ABORT";
  if (o.design.empty()) return !o.rightSet() ? "WRONG-SET" : !o.atFloor() ? "ABOVE" : "ok";
  if (o.drifts_named > 0) return "DRIFT";
  if (o.otherExtra()) return "EXTRA";
  if (!o.missing.empty() || !o.foreign_missing.empty()) return "MISSING";
  return !o.atFloor() ? "ABOVE" : "ok";
}

void printSeed(const Outcome& o) {
  std::string hidden;
  for (const nlohmann::json& f : o.foreign) hidden += (hidden.empty() ? "" : ", ") + foreignName(f);
  for (const DrawnMechanism& h : o.hidden) hidden += (hidden.empty() ? "" : ", ") + untestableName(h);
  std::printf("seed %4llu  %-9s  hidden: %s | named: %s | missing: %s | extra: %s | worst %.2fx floor"
              " | worse than the paper: %s",
              static_cast<unsigned long long>(o.seed), verdict(o), hidden.empty() ? "-" : hidden.c_str(),
              join(o.named).c_str(), join(o.missing).c_str(), join(o.extra).c_str(), o.worst_over_floor,
              join(o.worse_loads).c_str());
  if (!o.design.empty()) {
    std::printf(" | bearing tilt not named: %s | unexplained_trend: %s | unexplained: %s",
                join(o.foreign_missing).c_str(),
                o.unexplained_trend.empty() ? "-" : o.unexplained_trend.c_str(),
                o.unexplained.empty() ? "-" : o.unexplained.c_str());
  }
  std::printf("%s%s\n", o.error.empty() ? "" : " | ", o.error.c_str());
  std::fflush(stdout);
}

// p50, p90 and max of the worst load over the floor of the outcomes that did not abort.
std::array<double, 3> worstQuantiles(const std::vector<const Outcome*>& outcomes) {
  std::vector<double> worst;
  for (const Outcome* o : outcomes) {
    if (!o->abort()) worst.push_back(o->worst_over_floor);
  }
  if (worst.empty()) return {0.0, 0.0, 0.0};
  std::sort(worst.begin(), worst.end());
  const auto quantile = [&](double q) {
    return worst[std::min(worst.size() - 1, static_cast<size_t>(q * worst.size()))];
  };
  return {quantile(0.5), quantile(0.9), worst.back()};
}

void printSummary(const std::vector<Outcome>& outcomes) {
  int aborts = 0, right = 0, at_floor = 0, clean = 0, clean_right = 0, never_worse = 0;
  std::vector<const Outcome*> all;
  for (const Outcome& o : outcomes) {
    aborts += o.abort();
    never_worse += o.neverWorse();
    right += o.rightSet();
    at_floor += o.atFloor();
    if (o.hidden.empty()) {
      ++clean;
      clean_right += o.rightSet();
    }
    all.push_back(&o);
  }
  const auto [p50, p90, max] = worstQuantiles(all);
  std::printf("\n| seeds | aborts | named set right | clean named nothing | every load <= 1.5x floor | worst/floor p50 | p90 | max | never worse than the paper |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|\n");
  std::printf("| %zu | %d | %d | %d of %d | %d | %.2f | %.2f | %.2f | %d |\n", outcomes.size(), aborts,
              right, clean_right, clean, at_floor, p50, p90, max, never_worse);
}

// --foreign: a row per design and one for all.
void printForeignSummary(const std::vector<Outcome>& outcomes) {
  std::printf("\n| design | seeds | aborts | no drift named | no other cause named that is not in the data "
              "| catalogued found | bearing tilt named | every load <= 1.5x floor | worst/floor p50 | p90 | max "
              "| never worse than the paper |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const std::string design :
       {"bearing_tilt", "angle_dependent_stiffness", "beside", "both", "all"}) {
    std::vector<const Outcome*> rows;
    for (const Outcome& o : outcomes) {
      if (design == "all" || o.design == design) rows.push_back(&o);
    }
    if (rows.empty()) continue;
    int aborts = 0, no_drift = 0, no_extra = 0, hidden = 0, missed = 0, tilts = 0, tilts_named = 0,
        at_floor = 0, never_worse = 0;
    for (const Outcome* o : rows) {
      aborts += o->abort();
      no_drift += !o->abort() && o->drifts_named == 0;
      no_extra += !o->abort() && !o->otherExtra();
      hidden += static_cast<int>(o->hidden.size());
      missed += static_cast<int>(o->missing.size());
      tilts += static_cast<int>(o->foreign_found.size() + o->foreign_missing.size());
      tilts_named += static_cast<int>(o->foreign_found.size());
      at_floor += o->atFloor();
      never_worse += o->neverWorse();
    }
    const auto [p50, p90, max] = worstQuantiles(rows);
    std::printf("| %s | %zu | %d | %d | %d | %d of %d | %d of %d | %d | %.2f | %.2f | %.2f | %d |\n",
                design.c_str(), rows.size(), aborts, no_drift, no_extra, hidden - missed, hidden,
                tilts_named, tilts, at_floor, p50, p90, max, never_worse);
  }
}

// "1-200" or "1,5,9" (or a mix: "1-3,10").
std::vector<uint64_t> parseSeeds(const std::string& text) {
  std::vector<uint64_t> seeds;
  std::stringstream in(text);
  std::string part;
  while (std::getline(in, part, ',')) {
    const size_t dash = part.find('-');
    const uint64_t a = std::stoull(part.substr(0, dash));
    const uint64_t b = dash == std::string::npos ? a : std::stoull(part.substr(dash + 1));
    if (b < a) throw std::invalid_argument(part);
    for (uint64_t s = a; s <= b; ++s) seeds.push_back(s);
  }
  if (seeds.empty()) throw std::invalid_argument(text);
  return seeds;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"stepcal-diagnose-stress: the diagnosis on random mixes of hidden mechanisms"};
  std::string seeds_text = "1-10", work = "out/diagnose-stress", json_out;
  std::string stepcal = stepcal::bench::stepcalBesideThis();
  int jobs = 1;
  bool strict = false, foreign = false;
  std::string load_order = "blocks";
  app.add_option("--seeds", seeds_text, "seeds, e.g. 1-200 or 3,7,11")->capture_default_str();
  app.add_option("--out", work, "working folder (a campaign per seed)")->capture_default_str();
  app.add_option("--json", json_out, "file for every seed's outcome");
  app.add_option("--jobs", jobs, "seeds diagnosed at once")->check(CLI::Range(1, 64))->capture_default_str();
  app.add_option("--stepcal", stepcal, "the stepcal command to run")->capture_default_str();
  app.add_flag("--strict", strict, "also fail on a wrong named set or a load above 1.5x the floor");
  app.add_flag("--foreign", foreign,
               "hide load effects outside the catalogue (bearing_tilt, angle_dependent_stiffness, "
               "alone, beside a catalogued mechanism, or both) and judge drifts and extra causes "
               "named, and what the verdict leaves unexplained");
  app.add_option("--load-order", load_order,
                 "the campaigns' fit rows load block by load block as in the paper, or mixed "
                 "(stepcal simulate --load-order): load and time order then do not correlate")
      ->check(CLI::IsMember({"blocks", "mixed"}))
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  std::vector<uint64_t> seeds;
  try {
    seeds = parseSeeds(seeds_text);
  } catch (const std::exception&) {
    std::cerr << "stepcal-diagnose-stress: error: --seeds '" << seeds_text
              << "'; expected seeds and ranges such as 1-200 or 3,7,11\n";
    return 2;
  }
  if (!stepcal::bench::stepcalIsExecutable("stepcal-diagnose-stress", stepcal)) return 2;

  std::vector<Outcome> outcomes(seeds.size());
  std::atomic<size_t> next{0};
  std::mutex print;
  const auto worker = [&] {
    for (size_t i = next++; i < seeds.size(); i = next++) {
      outcomes[i] = diagnoseSeed(seeds[i], {stepcal, work, foreign, load_order});
      const std::lock_guard<std::mutex> lock(print);
      printSeed(outcomes[i]);
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < jobs; ++t) pool.emplace_back(worker);
  worker();
  for (std::thread& t : pool) t.join();

  if (foreign) {
    printForeignSummary(outcomes);
  } else {
    printSummary(outcomes);
  }
  const auto count = [&](bool (Outcome::*test)() const) {
    return std::count_if(outcomes.begin(), outcomes.end(), [&](const Outcome& o) { return (o.*test)(); });
  };
  const auto aborts = count(&Outcome::abort), right = count(&Outcome::rightSet),
             at_floor = count(&Outcome::atFloor);
  if (!json_out.empty()) {
    nlohmann::json all = nlohmann::json::array();
    for (const Outcome& o : outcomes) all.push_back(toJson(o));
    std::ofstream(json_out) << all.dump(2) << "\n";
  }
  const auto seeds_run = static_cast<std::ptrdiff_t>(outcomes.size());
  const bool failed = aborts > 0 || (strict && (right < seeds_run || at_floor < seeds_run));
  return failed ? 1 : 0;
}
