// Fanuc TP as exported (.LS): the /POS section's positions P[n]{ GP1: UF : u, UT : t,
// CONFIG : 'N U T, 0, 0, 0', X = … mm, Y, Z, W = … deg, P, R } (W, P, R about the fixed X, Y, Z)
// or { GP1: UF : u, UT : t, J1 = … deg, …, J6 } (joints; extended axes E1 … kept). Group 1 is
// the robot: its numbers are the target; every other group is read and kept. The user and tool
// frames are named by number (UF 2, UT 9): their values from UTOOL[n]=PR[i] / UFRAME[n]=PR[i]
// after PR[i,1..6]=… in /MN (as RoboDK writes them), else from the command line. A motion
// in /MN to a position register (PR[…]) or with Offset, Tool_Offset or INC is moved at run time:
// reported, and its P[n] is not corrected. PAYLOAD[n] in /MN selects a payload schedule (its
// values are the controller's, given on the command line) for the motions after it; a P[n]
// takes the payload of the first motion to it. Tabs, leading-dot numbers and P[n:"comment"] are
// read; the file must end with /END.
#include <array>
#include <cstdio>
#include <map>
#include <optional>
#include <set>

#include "scan.hpp"
#include "stepcal/common/units.hpp"

namespace stepcal::programs::detail {
namespace {

class TpReader {
 public:
  TpReader(std::string_view text, const std::string& path) : s_(text, path) {
    program_.language = Language::kFanucTp;
    program_.orientation = Orientation::kFixedXyzDeg;
    program_.file_units_per_m = 1000.0;
    program_.file_units_per_rad = 1.0 / kRadPerDeg;
  }

  Program read() {
    std::string section;
    while (true) {
      s_.skipSpace();
      if (s_.atEnd()) break;
      if (s_.peek() == '/') {
        s_.advance();
        section = lowerCase(s_.word());
        if (section == "end") {
          ended_ = true;
          s_.skipSpace();
          if (!s_.atEnd()) s_.fail("text after /END; expected the end of the file");
          break;
        }
        skipLine();
      } else if (section == "pos") {
        position();
      } else if (section == "mn") {
        instruction();
      } else {
        skipLine();
      }
    }
    if (!ended_) s_.failAt(s_.text().size(), "the file ends without /END: a truncated program, or not a TP export");
    dropMovedAtRunTime();
    return std::move(program_);
  }

 private:
  void skipLine() {
    while (!s_.atEnd() && s_.peek() != '\n') s_.advance();
  }

  /// A /MN line: a motion to PR[…], or to P[n] with an offset, is reported.
  void instruction() {
    const size_t start = s_.pos();
    std::string_view line = s_.restOfLine();
    skipLine();
    const size_t colon = line.find(':');
    if (colon == std::string_view::npos) return;
    std::string body = lowerCase(line.substr(colon + 1));
    if (frameAssignment(body) || payloadSchedule(body)) return;
    const size_t first = body.find_first_not_of(" \t");
    if (first == std::string::npos || std::string("jlca").find(body[first]) == std::string::npos ||
        (body.size() > first + 1 && body[first + 1] != ' ' && body[first + 1] != '\t')) {
      return;
    }
    for (size_t p = body.find("p[", first); p != std::string::npos; p = body.find("p[", p + 2)) {
      if (p == 0 || !isWordChar(body[p - 1])) motionTo(std::atoi(body.c_str() + p + 2), s_.lineOf(start));
    }
    const bool register_target = body.find("pr[", first) == first + 2 || body.find(" pr[") != std::string::npos;
    const bool offset = body.find("offset") != std::string::npos || body.find(" inc") != std::string::npos;
    if (!register_target && !offset) return;
    program_.not_literals.push_back({s_.lineOf(start), s_.columnOf(start) + int(colon) + 1,
                                     std::string(line.substr(colon + 1))});
    const size_t p = body.find("p[");
    if (!register_target && p != std::string::npos) {
      moved_.insert(std::atoi(body.c_str() + p + 2));
    }
  }

  /// PR[i,j]=value and UTOOL[n]=PR[i] / UFRAME[n]=PR[i] (as RoboDK writes a tool and a frame):
  /// UT n and UF n from the register's X, Y, Z, W, P, R. A frame assigned twice with other values
  /// is left to the command line (a position would depend on where it runs).
  bool frameAssignment(const std::string& body) {
    int i = 0, j = 0, n = 0;
    double value = 0.0;
    char close = 0;
    if (std::sscanf(body.c_str(), " pr[%d,%d]=%lf %c", &i, &j, &value, &close) == 4 && close == ';' && j >= 1 && j <= 6) {
      registers_[i][size_t(j - 1)] = value;
      return true;
    }
    const bool tool = std::sscanf(body.c_str(), " utool[%d]=pr[%d] %c", &n, &i, &close) == 3;
    if (!tool && std::sscanf(body.c_str(), " uframe[%d]=pr[%d] %c", &n, &i, &close) != 3) return false;
    const auto found = registers_.find(i);
    if (close != ';' || found == registers_.end()) return true;
    const std::array<std::optional<double>, 6>& r = found->second;
    std::vector<double> xyzwpr;
    for (const std::optional<double>& v : r) {
      if (!v) return true;
      xyzwpr.push_back(*v);
    }
    const std::string name = (tool ? "UT " : "UF ") + std::to_string(n);
    Frame& f = program_.frames[size_t(frameIndex(name, false))];
    const Pose X = poseFromWritten(xyzwpr, Orientation::kFixedXyzDeg, 1000.0);
    if (assigned_.insert(name).second) {
      f.X = X;
    } else if (f.X && !f.X->isApprox(X, 1e-12)) {
      f.X.reset();
    }
    return true;
  }

  /// A motion to P[n] on `line` under the payload in force: P[n]'s load is the first one's; the
  /// others are said on its report line.
  void motionTo(int position, int line) {
    const auto [first, inserted] = load_of_position_.emplace(position, current_payload_);
    if (inserted || first->second == current_payload_) return;
    std::string& others = other_loads_[position];
    others += std::string(others.empty() ? "" : ", ") + "line " + std::to_string(line) + " under " +
              (current_payload_ < 0 ? std::string("no payload") : program_.loads[size_t(current_payload_)].name);
  }

  /// PAYLOAD[n] ; or PAYLOAD[n:comment] ; : payload schedule n for the motions after it.
  bool payloadSchedule(const std::string& body) {
    int n = 0;
    char after = 0;
    if (std::sscanf(body.c_str(), " payload[%d%c", &n, &after) != 2 || (after != ']' && after != ':')) return false;
    current_payload_ = loadIndex(program_, "PAYLOAD[" + std::to_string(n) + "]");
    return true;
  }

  /// P[n] or P[n:"comment"] { GP1: … , GP2: … };
  void position() {
    const size_t start = s_.pos();
    if (!s_.acceptWord("P") || !s_.accept('[', false)) s_.fail("'" + std::string(s_.restOfLine().substr(0, 20)) + "' in /POS; expected P[n]{");
    const int number = int(s_.number("a position's number", nullptr, false));
    if (s_.accept(':', false)) {
      s_.skipBlanks();
      if (s_.peek() != '"') s_.fail("a position's comment that is not in quotes");
      s_.advance();
      while (!s_.atEnd() && s_.peek() != '"' && s_.peek() != '\n') s_.advance();
      s_.expect('"', "a position's comment", false);
    }
    s_.expect(']', "a position's name", false);
    s_.expect('{', "a position");
    while (!s_.accept('}')) {
      if (s_.atEnd()) s_.failAt(start, "a position that the file ends in; expected '}'");
      group(number);
    }
    s_.expect(';', "a position");
  }

  void group(int number) {
    s_.skipSpace();
    const size_t start = s_.pos();
    const std::string gp = lowerCase(s_.word());
    if (gp.rfind("gp", 0) != 0 || !s_.accept(':')) s_.failAt(start, "'" + gp + "' in a position; expected GP1: (a group)");
    int uf = -1, ut = -1;
    std::string configuration;
    std::map<std::string, std::pair<NumberField, double>> values;
    while (true) {
      s_.skipSpace();
      if (s_.peek() == '}' || s_.atEnd()) break;
      const size_t item = s_.pos();
      if (lowerCase(s_.text().substr(item, 2)) == "gp" && item + 2 < s_.text().size() && std::isdigit(static_cast<unsigned char>(s_.text()[item + 2]))) break;
      const std::string key = lowerCase(s_.word());
      if (key.empty()) s_.fail("'" + std::string(s_.restOfLine().substr(0, 20)) + "' in a position; expected a name (UF, UT, CONFIG, X, J1 …)");
      if (key == "uf" || key == "ut") {
        s_.expect(':', "UF or UT");
        (key == "uf" ? uf : ut) = int(s_.number("UF or UT"));
      } else if (key == "config") {
        s_.expect(':', "CONFIG");
        s_.skipBlanks();
        const size_t q = s_.pos();
        s_.expect('\'', "CONFIG", false);
        while (!s_.atEnd() && s_.peek() != '\'' && s_.peek() != '\n') s_.advance();
        s_.expect('\'', "CONFIG", false);
        configuration = std::string(s_.text().substr(q + 1, s_.pos() - q - 2));
      } else {
        s_.expect('=', "a position's value");
        NumberField f;
        const double v = s_.number("a position's value", &f);
        const std::string unit = lowerCase(s_.word());
        if (unit != "mm" && unit != "deg") s_.failAt(item, "'" + key + "' without its unit; expected mm or deg");
        if (!values.emplace(key, std::make_pair(f, v)).second) s_.failAt(item, "'" + key + "' twice in a group");
      }
      s_.accept(',');
    }
    if (gp == "gp1") robotGroup(start, number, uf, ut, configuration, values);
  }

  void robotGroup(size_t start, int number, int uf, int ut, const std::string& configuration,
                  const std::map<std::string, std::pair<NumberField, double>>& values) {
    const bool cartesian = values.count("x") > 0;
    const std::vector<std::string> names = cartesian ? std::vector<std::string>{"x", "y", "z", "w", "p", "r"}
                                                     : std::vector<std::string>{"j1", "j2", "j3", "j4", "j5", "j6"};
    std::vector<NumberField> fields;
    std::vector<double> written;
    for (const std::string& n : names) {
      const auto found = values.find(n);
      if (found == values.end()) s_.failAt(start, "P[" + std::to_string(number) + "] GP1 without " + n + "; expected X … R or J1 … J6");
      fields.push_back(found->second.first);
      written.push_back(found->second.second);
    }
    Target t = cartesian ? cartesianTarget(program_, fields, written, s_.lineOf(start), s_.columnOf(start))
                         : jointTarget(program_, fields, written, s_.lineOf(start), s_.columnOf(start));
    t.name = "P[" + std::to_string(number) + "]";
    t.configuration = configuration;
    if (uf >= 0) t.base = frameIndex("UF " + std::to_string(uf), uf == 0);
    if (ut >= 0) t.tool = frameIndex("UT " + std::to_string(ut), false);
    const auto load = load_of_position_.find(number);
    if (load != load_of_position_.end()) t.load = load->second;
    if (other_loads_.count(number)) t.other_loads = other_loads_.at(number);
    program_.targets.push_back(std::move(t));
  }

  int frameIndex(const std::string& name, bool identity) {
    for (size_t i = 0; i < program_.frames.size(); ++i) {
      if (program_.frames[i].name == name) return int(i);
    }
    Frame f{name, std::nullopt};
    if (identity) f.X = Pose::Identity();
    program_.frames.push_back(f);
    return int(program_.frames.size() - 1);
  }

  /// P[n] moved by an offset at run time: not corrected.
  void dropMovedAtRunTime() {
    std::vector<Target> kept;
    for (Target& t : program_.targets) {
      const bool moved = moved_.count(std::atoi(t.name.c_str() + 2)) > 0;
      if (!moved) kept.push_back(std::move(t));
    }
    program_.targets = std::move(kept);
  }

  Scanner s_;
  Program program_;
  std::set<int> moved_;
  std::map<int, std::array<std::optional<double>, 6>> registers_;  ///< PR[i,1..6] as assigned
  std::set<std::string> assigned_;  ///< UT n and UF n assigned from a register
  int current_payload_ = -1;        ///< the PAYLOAD[n] in force in /MN (an index into loads)
  std::map<int, int> load_of_position_;  ///< P[n]: the payload of the first motion to it
  std::map<int, std::string> other_loads_;  ///< P[n]: the later motions to it under another payload
  bool ended_ = false;
};

}  // namespace

Program readFanucTp(std::string_view text, const std::string& path) {
  return TpReader(text, path).read();
}

}  // namespace stepcal::programs::detail
