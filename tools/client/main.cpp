// stepcal-client: sends correction requests to stepcal-runtime over LCM and measures the answers.
//
//   stepcal-client --forward q1 … q6 [--wrench fx fy fz mx my mz] [--temp-c T]
//                                                        one request, deg / N, N·m / °C
//   stepcal-client --forward q1 … q6 --count N --rate HZ [--json]
//                                                        the same request N times at HZ (live
//                                                        wrench unless --wrench): each reply's
//                                                        send time, status and wrench age;
//                                                        SIGINT/SIGTERM stops it early
//   stepcal-client --inverse x y z qw qx qy qz [--seed q1 … q6] [--wrench …] [--temp-c T]
//                                                        mm, unit quaternion, in --frame; deg
//   stepcal-client --campaign DIR [--set validation] [--mode forward|inverse] [--count N]
//                  [--rate HZ] [--truth truth.json] [--live-wrench [--wrench-channel C]] [--json]
//   stepcal-client --ping N [--json]     raw LCM round trips to a `stepcal-client --echo`
//   stepcal-client --echo                answers STEPCAL_PING on STEPCAL_PONG until SIGINT/SIGTERM
//   stepcal-client --sensor-command bias|clear-bias|reset
//                                        one sensor_command_t to the daemon's CAN sensor
//
// Single requests in the controller's terms (docs/runtime.md, "Integration"): --frame
// tracker|base|user [--user-frame x y z qw qx qy qz] (the user frame in the base frame, mm),
// --tool x y z qw qx qy qz [--tool-from target|flange] (the TCP, mm), --payload KG [--cog x y z]
// [--cog-frame flange|tool] (the load data: mass and centre of gravity, mm) instead of --wrench.
// Every length on the command line is in mm and every angle in degrees, as in `stepcal correct`
// and the campaign files; the messages carry SI. The exit statuses: exit_codes.hpp.
// --key-file FILE: requests and sensor commands carry the cell key's code, and replies whose
// code does not verify or whose counter is not fresh are rejected (counted, never matched).
//
// Replies are matched to requests by request_id; a reply later than --timeout-ms counts as lost.
// Without --rate one request is in flight at a time (the next goes when the reply arrives or
// times out); with --rate requests leave on a fixed schedule. Campaign rows carry their measured
// wrench (wrench_source = given) and temperature (temp_c; NaN where the row has none), single
// requests --temp-c (default NaN: not measured). Accuracy counts OK replies only. Forward
// accuracy is against the rows' measured poses; inverse requests ask for the measured pose from
// a seed 2° off the row's joints (alternating sign), and their accuracy is against the twin's
// truth (where the true robot goes at q_target) when --truth is given, else the solver's own
// residual. Forward answers are also checked against the truth (where the true robot goes at q)
// when --truth is given.
//
// --live-wrench: the requests use the daemon's live sensor instead of the rows' wrenches. Before
// each request the client publishes the row's joints and payload as robot_state_t, waits until a
// simulated sensor (stepcal-ftsim --truth) echoes it as applied, then until the daemon has taken
// two samples stamped after the echo (wrench_t on --wrench-channel, where stepcal-runtime
// --sensor-republish puts each sample it took): the first may still be the reading the sensor
// made just before it applied the state. The report adds the latency from the CAN frame (the
// reply's wrench_stamp_ns) to the reply.
//
// --check-model FILE (repeatable): every reply is recomputed offline with the model file whose
// model_id it carries, through the daemon's own code (decodeRequest, the runtime's calls,
// service::writeAnswer); an inverse reply with the iteration cap set to the iterations it took,
// since the daemon's deadline may have cut it short. A reply whose values differ (more than
// 1e-12) or whose model_id is none of the files' is a torn answer: exit status 1.
#include <CLI/CLI.hpp>

#include <cmath>
#include <iostream>

#include "client.hpp"

namespace stepcal::client {
namespace {

void addOptions(CLI::App& app, Args& args) {
  app.add_option("--lcm-url", args.lcm_url, "LCM URL")->capture_default_str();
  app.add_option("--forward", args.forward_q_deg, "one forward request: joints q1..q6, deg")
      ->expected(6);
  app.add_option("--inverse", args.inverse_pose,
                 "one inverse request: TCP position x y z (mm) and quaternion qw qx qy qz in "
                 "--frame (default: the tracker frame; the TCP is the measured target without "
                 "--tool)")
      ->expected(7);
  app.add_option("--seed", args.seed_q_deg, "inverse: joints to start from, deg (default 0)")
      ->expected(6);
  app.add_option("--wrench", args.wrench,
                 "given wrench on the sensor, fx fy fz (N) mx my mz (N m), sensor axes "
                 "(default: the daemon's live sensor)")
      ->expected(6);
  app.add_option("--temp-c", args.temp_c,
                 "structure temperature of a single request, °C, within -50 … 150 (default: not "
                 "measured, no thermal correction)");
  app.add_option("--campaign", args.campaign_dir, "send a campaign's rows");
  app.add_option("--set", args.set, "campaign rows: geometry | stiffness | residual | validation")
      ->capture_default_str();
  app.add_option("--mode", args.mode, "campaign requests: forward | inverse")->capture_default_str();
  app.add_option("--count", args.count,
                 "campaign requests to send (rows cycle; default: one per row); with --forward: "
                 "send it this many times (with --rate)");
  app.add_option("--rate", args.rate_hz, "requests per second (default: one in flight at a time)");
  app.add_option("--truth", args.truth_path, "the twin's truth.json to check answers against");
  app.add_flag("--live-wrench", args.live_wrench,
               "campaign: use the daemon's live sensor; publish each row's joints and payload as "
               "robot_state_t first");
  app.add_option("--wrench-channel", args.wrench_channel,
                 "--live-wrench: channel of the daemon's samples (stepcal-runtime --sensor-republish)")
      ->capture_default_str();
  app.add_option("--ping", args.ping_count, "raw LCM round trips to `stepcal-client --echo`");
  app.add_flag("--echo", args.echo, "answer STEPCAL_PING on STEPCAL_PONG until stopped");
  app.add_option("--deadline-us", args.deadline_us,
                 "request deadline, us (0: the daemon's budget)")->capture_default_str();
  app.add_option("--timeout-ms", args.timeout_ms, "a reply later than this is lost, ms")
      ->capture_default_str();
  app.add_flag("--json", args.json, "print JSON");
  app.add_option("--check-model", args.check_models,
                 "campaign: recompute every reply with the model file whose id it carries; "
                 "repeat for every model the daemon may serve")
      ->take_all();
  app.add_option("--frame", args.frame,
                 "single request: frame of its poses: tracker | base | user")->capture_default_str();
  app.add_option("--user-frame", args.user_frame,
                 "--frame user: the user frame in the robot base frame, x y z (mm) qw qx qy qz")
      ->expected(7);
  app.add_option("--tool", args.tool, "single request: the TCP, x y z (mm) qw qx qy qz, from "
                                      "--tool-from (default: none, the measured target)")
      ->expected(7);
  app.add_option("--tool-from", args.tool_from,
                 "what --tool is given from: target (the measured target) | flange (the "
                 "controller's tool data)")
      ->capture_default_str();
  app.add_option("--payload", args.payload_kg,
                 "single request: the payload's mass, kg (its weight replaces --wrench)");
  app.add_option("--cog", args.cog_mm, "--payload: centre of gravity x y z, mm, in --cog-frame")
      ->expected(3);
  app.add_option("--cog-frame", args.cog_frame, "--cog's frame: flange | tool")
      ->capture_default_str();
  app.add_option("--sensor-command", args.sensor_command,
                 "send one sensor_command_t: bias | clear-bias | reset");
  app.add_option("--key-file", args.key_file,
                 "the cell's key (32 bytes, mode 0600): seal requests and sensor commands, "
                 "verify replies");
}

/// Throws InputError for options that do not go together.
void checkArgs(const Args& args) {
  const int modes = int(!args.forward_q_deg.empty()) + int(!args.inverse_pose.empty()) +
                    int(!args.campaign_dir.empty()) + int(args.ping_count > 0) + int(args.echo) +
                    int(!args.sensor_command.empty());
  if (modes != 1) {
    throw InputError("choose exactly one of --forward, --inverse, --campaign, --ping N, --echo, "
                     "--sensor-command");
  }
  const bool single = !args.forward_q_deg.empty() || !args.inverse_pose.empty();
  if (!single && (args.frame != "tracker" || !args.user_frame.empty() || !args.tool.empty() ||
                  args.tool_from != "target" || args.payload_kg >= 0.0 || !args.cog_mm.empty() ||
                  args.cog_frame != "flange")) {
    throw InputError("--frame, --user-frame, --tool, --tool-from, --payload, --cog and "
                     "--cog-frame go with --forward or --inverse");
  }
  if (!(args.timeout_ms > 0.0)) throw InputError("--timeout-ms must be > 0");
  if (!(args.rate_hz >= 0.0)) throw InputError("--rate must be ≥ 0");
  if (args.count > 0 && args.campaign_dir.empty() &&
      (args.forward_q_deg.empty() || !(args.rate_hz > 0.0))) {
    throw InputError("--count goes with --campaign, or with --forward and --rate");
  }
  if (!args.seed_q_deg.empty() && args.inverse_pose.empty()) {
    throw InputError("--seed goes with --inverse");
  }
  if (!args.wrench.empty() && args.forward_q_deg.empty() && args.inverse_pose.empty()) {
    throw InputError("--wrench goes with --forward or --inverse (campaign rows carry their own)");
  }
  if (!std::isnan(args.temp_c) &&
      (!runtime::validTemperature(args.temp_c) ||
       (args.forward_q_deg.empty() && args.inverse_pose.empty()))) {
    throw InputError("--temp-c goes with --forward or --inverse and lies within " +
                     std::to_string(int(runtime::kMinTemperature_c)) + " … " +
                     std::to_string(int(runtime::kMaxTemperature_c)) +
                     " °C (campaign rows carry their own)");
  }
}

}  // namespace
}  // namespace stepcal::client

int main(int argc, char** argv) {
  using namespace stepcal::client;
  CLI::App app{"stepcal-client: requests to stepcal-runtime over LCM; latency and accuracy"};
  Args args;
  addOptions(app, args);
  app.footer(stepcal::exit_code::kHelpFooter);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help is done (0); any other parse error is bad usage, whatever CLI11's own number.
    return app.exit(e) == 0 ? stepcal::exit_code::kDone : stepcal::exit_code::kBadInput;
  }

  try {
    checkArgs(args);
    if (args.echo) return runEcho(args);
    if (!args.sensor_command.empty()) return runSensorCommand(args);
    if (args.ping_count > 0) return runPing(args);
    if (!args.campaign_dir.empty()) return runCampaign(args);
    return runSingle(args);
  } catch (const stepcal::InputError& e) {
    std::cerr << "stepcal-client: error: " << e.what() << "\n";
    return stepcal::exit_code::kBadInput;
  }
}
