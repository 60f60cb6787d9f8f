// The daemon's options (see daemon_options.hpp).
#include "stepcal/service/daemon_options.hpp"

#include "stepcal/service/auth.hpp"

#include <getopt.h>

#include <charconv>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <map>
#include <sstream>
#include <string_view>
#include <vector>

#include "stepcal/common/error.hpp"
#include "stepcal/common/exit_codes.hpp"
#include "stepcal/common/text_number.hpp"

namespace stepcal::service {

static_assert(kDaemonAuthWindowMs * 1000 == kDefaultAuthWindowUs,
              "the daemon's default window is the verifier's");
namespace {

// ---- values -------------------------------------------------------------------------------------

// Each parser throws InputError(where + ": expected …, got '…'"); `where` names the option
// ("--budget-us") or the file's key ("key 'budget-us'", with the file and line passed on).
struct Where {
  std::string what;  ///< "--budget-us" or "key 'budget-us'"
  std::string file;  ///< the configuration file, or "" on the command line
  int line = 0;
};

[[noreturn]] void refuse(const Where& where, const std::string& expected, std::string_view text) {
  throw InputError(where.what + ": expected " + expected + ", got " + inQuotes(text), where.file,
                   where.line);
}

void parseValue(std::string_view text, std::string& value, const Where&) { value = text; }

void parseValue(std::string_view text, int& value, const Where& where) {
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (text.empty() || error != std::errc() || end != text.data() + text.size()) {
    refuse(where, "an integer", text);
  }
}

void parseValue(std::string_view text, uint32_t& value, const Where& where) {
  // Decimal or 0x-prefixed hexadecimal (CAN ids are written in hex).
  const bool hex = text.size() > 2 && text[0] == '0' && (text[1] == 'x' || text[1] == 'X');
  const std::string_view digits = hex ? text.substr(2) : text;
  const auto [end, error] =
      std::from_chars(digits.data(), digits.data() + digits.size(), value, hex ? 16 : 10);
  if (digits.empty() || error != std::errc() || end != digits.data() + digits.size()) {
    refuse(where, "a non-negative integer (decimal or 0x hex)", text);
  }
}

void parseValue(std::string_view text, double& value, const Where& where) {
  const std::optional<double> parsed = parseFinite(text);
  if (!parsed) refuse(where, "a finite number", text);
  value = *parsed;
}

void parseValue(std::string_view text, bool& value, const Where& where) {
  if (text == "true") {
    value = true;
  } else if (text == "false") {
    value = false;
  } else {
    refuse(where, "true or false", text);
  }
}

std::string formatValue(const std::string& value) { return value; }
std::string formatValue(int value) { return std::to_string(value); }
std::string formatValue(uint32_t value) {
  std::ostringstream out;
  out << "0x" << std::hex << value;
  return out.str();
}
std::string formatValue(double value) { return formatShortest(value); }
std::string formatValue(bool value) { return value ? "true" : "false"; }

// ---- the table ----------------------------------------------------------------------------------

/// A field of DaemonArgs, reached through a path of member pointers (args.*A.*B).
template <auto... Path>
auto& fieldOf(DaemonArgs& args) {
  return (args.*....*Path);
}
template <auto... Path>
const auto& fieldOf(const DaemonArgs& args) {
  return (args.*....*Path);
}

struct Field {
  void (*set)(DaemonArgs&, std::string_view, const Where&);
  std::string (*get)(const DaemonArgs&);
  bool flag;  ///< a bool: on the command line it needs no value (--realtime = --realtime=true)
};

template <auto... Path>
Field field() {
  using Value = std::decay_t<decltype(fieldOf<Path...>(std::declval<DaemonArgs&>()))>;
  return {[](DaemonArgs& args, std::string_view text, const Where& where) {
            parseValue(text, fieldOf<Path...>(args), where);
          },
          [](const DaemonArgs& args) { return formatValue(fieldOf<Path...>(args)); },
          std::is_same_v<Value, bool>};
}

struct DaemonOption {
  const char* name;   ///< the long option without "--", and the configuration file's key
  const char* value;  ///< the value's form in --help
  const char* help;
  Field field;
};

using S = SensorArgs;
using A = DaemonArgs;

// Every option of the daemon, one line each.
const std::vector<DaemonOption>& options() {
  static const std::vector<DaemonOption> table = {
      {"model", "FILE", "model file (stepcal calibrate --out); required", field<&A::model_path>()},
      {"lcm-url", "URL", "LCM URL", field<&A::lcm_url>()},
      {"budget-us", "N", "longest time from a request's arrival to its reply, us", field<&A::budget_us>()},
      {"max-wrench-age-ms", "MS", "a live wrench older than this gives STALE_WRENCH, ms", field<&A::max_wrench_age_ms>()},
      {"sensor", "lcm|can:IFACE", "source of the live wrench: lcm (wrench_t on wrench-channel) or can:IFACE (ATI Net CAN OEM F/T sensor on SocketCAN interface IFACE)", field<&A::sensor, &S::sensor>()},
      {"wrench-channel", "CHANNEL", "sensor lcm: channel of the live wrench_t samples", field<&A::sensor, &S::wrench_channel>()},
      {"sensor-base-id", "ID", "sensor can: the sensor's base id, 0 ... 0x7F (CAN ids base << 4 | opcode)", field<&A::sensor, &S::base_id>()},
      {"sensor-rate-hz", "HZ", "sensor can: gauge polls per second", field<&A::sensor, &S::rate_hz>()},
      {"sensor-calibration", "INDEX", "sensor can: calibration index made active at start-up, 0 ... 15 (-1 keeps the sensor's)", field<&A::sensor, &S::calibration_index>()},
      {"sensor-bias-samples", "N", "sensor can: readings averaged per bias (sensor_command_t BIAS)", field<&A::sensor, &S::bias_samples>()},
      {"sensor-republish", "CHANNEL", "sensor can: also publish every sample as wrench_t on this channel (empty: none)", field<&A::sensor, &S::republish_channel>()},
      {"realtime", "true|false", "mlockall and SCHED_FIFO priority 80 (needs CAP_IPC_LOCK and CAP_SYS_NICE or the matching rlimits)", field<&A::realtime>()},
      {"key-file", "FILE", "the cell's shared key (32 bytes, mode 0600): requests and sensor commands must carry its code, replies carry the daemon's; empty: the systemd credential cell-key when the unit hands one over (LoadCredential=), else no authentication", field<&A::key_file>()},
      {"auth-window-ms", "MS", "key-file: how far a message's counter (its send time) may lie from this host's clock, ms", field<&A::auth_window_ms>()},
  };
  return table;
}

// Options of the command line only (not configuration keys): after the table's in getopt's list.
enum MetaOption { kConfig = 1000, kPrintConfig, kHelp };

const DaemonOption* findOption(std::string_view name) {
  for (const DaemonOption& option : options()) {
    if (name == option.name) return &option;
  }
  return nullptr;
}

std::string keyList() {
  std::string keys;
  for (const DaemonOption& option : options()) keys += (keys.empty() ? "" : ", ") + std::string(option.name);
  return keys;
}

std::string_view trimmed(std::string_view text) {
  const size_t begin = text.find_first_not_of(" \t\r");
  if (begin == std::string_view::npos) return {};
  const size_t end = text.find_last_not_of(" \t\r");
  return text.substr(begin, end - begin + 1);
}

/// Words of a help text wrapped at 96 columns, each line after the first indented by `indent`.
std::string wrapped(std::string_view text, size_t first_column, const std::string& indent) {
  std::string out;
  size_t column = first_column;
  std::istringstream words{std::string(text)};
  for (std::string word; words >> word;) {
    if (column > indent.size() && column + 1 + word.size() > 96) {
      out += "\n" + indent;
      column = indent.size();
    } else if (column > first_column || !out.empty()) {
      out += ' ';
      ++column;
    }
    out += word;
    column += word.size();
  }
  return out;
}

}  // namespace

void readDaemonConfiguration(const std::string& path, DaemonArgs& args) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError("cannot open the configuration file", path);
  std::map<std::string, int, std::less<>> first_line;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    const std::string_view text = trimmed(line);
    if (text.empty() || text[0] == '#') continue;
    if (text.find('\0') != std::string_view::npos) {
      throw InputError("expected text, found a NUL byte", path, number);
    }
    const size_t equals = text.find('=');
    if (equals == std::string_view::npos) {
      throw InputError("expected 'key = value', got " + inQuotes(text), path, number);
    }
    const std::string key(trimmed(text.substr(0, equals)));
    const DaemonOption* option = findOption(key);
    if (option == nullptr) {
      throw InputError("unknown key " + inQuotes(key) + " (expected one of: " + keyList() + ")",
                       path, number);
    }
    if (const auto seen = first_line.find(key); seen != first_line.end()) {
      throw InputError("key " + inQuotes(key) + " given twice (first on line " +
                           std::to_string(seen->second) + ")",
                       path, number);
    }
    first_line.emplace(key, number);
    option->field.set(args, trimmed(text.substr(equals + 1)), {"key " + inQuotes(key), path, number});
  }
  if (in.bad()) throw InputError("cannot read the configuration file", path);
}

DaemonCommandLine parseDaemonCommandLine(int argc, char** argv) {
  std::vector<option> long_options;
  for (const DaemonOption& entry : options()) {
    long_options.push_back({entry.name, entry.field.flag ? optional_argument : required_argument,
                            nullptr, int(&entry - options().data())});
  }
  long_options.push_back({"config", required_argument, nullptr, kConfig});
  long_options.push_back({"print-config", no_argument, nullptr, kPrintConfig});
  long_options.push_back({"help", no_argument, nullptr, kHelp});
  long_options.push_back({nullptr, 0, nullptr, 0});

  // The file first, then the command line over it, whatever the order given.
  DaemonCommandLine result;
  std::string config_path;
  std::vector<std::pair<const DaemonOption*, std::string>> given;
  opterr = 0;  // our messages, not getopt's
  optind = 0;  // a full re-initialisation (glibc), so that a second parse starts afresh
  // '+': stop at the first argument that is no option (refused below); ':': a missing value
  // returns ':' rather than '?'.
  for (int code; (code = getopt_long(argc, argv, "+:", long_options.data(), nullptr)) != -1;) {
    const std::string arg = argv[optind - 1];
    if (code == '?') throw InputError("unknown option " + inQuotes(arg) + " (see --help)");
    if (code == ':') throw InputError("option " + inQuotes(arg) + " needs a value (see --help)");
    if (code == kConfig) {
      config_path = optarg;
    } else if (code == kPrintConfig) {
      result.print_config = true;
    } else if (code == kHelp) {
      result.help = true;
    } else {
      const DaemonOption& entry = options()[size_t(code)];
      given.emplace_back(&entry, optarg != nullptr ? optarg : "true");
    }
  }
  if (optind < argc) {
    throw InputError("unexpected argument " + inQuotes(argv[optind]) +
                     " (options are --name VALUE or --name=VALUE; see --help)");
  }
  if (!config_path.empty()) readDaemonConfiguration(config_path, result.args);
  for (const auto& [entry, value] : given) {
    entry->field.set(result.args, value, {"--" + std::string(entry->name), {}, 0});
  }
  if (result.args.model_path.empty() && !result.help && !result.print_config) {
    throw InputError("no model file: give --model FILE or 'model = FILE' in the --config file");
  }
  return result;
}

std::string daemonUsage() {
  const DaemonArgs defaults;
  std::string out =
      "stepcal-runtime: corrects commanded poses and inverts desired poses over LCM\n"
      "usage: stepcal-runtime [--config FILE] [--OPTION VALUE ...]\n\n"
      "  --config FILE        read options from FILE first (`key = value` lines, keys as the\n"
      "                       options below without --); options given here override it\n"
      "  --print-config       print the configuration these options make, as such a file\n"
      "  --help               print this\n";
  const std::string indent(23, ' ');
  for (const DaemonOption& option : options()) {
    std::string head = "  --" + std::string(option.name) +
                       (option.field.flag ? "[=" + std::string(option.value) + "]"
                                          : " " + std::string(option.value));
    if (head.size() < indent.size() - 1) head.resize(indent.size(), ' ');
    else head += "\n" + indent;
    std::string help = option.help;
    const std::string value = option.field.get(defaults);
    if (!value.empty()) help += " (default " + value + ")";
    out += head + wrapped(help, indent.size(), indent) + "\n";
  }
  // The daemon itself ends with 0 (stopped by SIGINT/SIGTERM) or 2 (bad input at start).
  return out + "\n" + exit_code::kHelpFooter + "\n";
}

std::string daemonConfiguration(const DaemonArgs& args) {
  std::string out =
      "# stepcal-runtime configuration: `key = value`, keys as the daemon's long options\n"
      "# (stepcal-runtime --help); an option on the command line overrides its key here.\n";
  for (const DaemonOption& option : options()) {
    out += "\n# " + wrapped(option.help, 2, "# ") + "\n";
    out += std::string(option.name) + " = " + option.field.get(args) + "\n";
  }
  return out;
}

}  // namespace stepcal::service
