// KUKA KRL (.src and .dat): the aggregates {X …, Y …, Z …, A …, B …, C …[, S …, T …, E1 …]} (POS,
// E6POS, FRAME) and {A1 …, …, A6 …[, E1 …]} (AXIS, E6AXIS), inline in PTP/LIN/CIRC (and their
// spline forms) or declared (DECL E6POS XP1={…}, XP1={…}); $TOOL and $BASE from an inline
// {FRAME: …}, TOOL_DATA[n]/BASE_DATA[n] (their values where the file assigns them) or
// BAS(#TOOL, n); $LOAD from an inline {M …, CM {X …, Y …, Z …, …}, J {…}} or LOAD_DATA[n]
// (BAS(#TOOL, n) selects LOAD_DATA[n] too, as KUKA's BAS does). Keywords in any case; ';'
// starts a comment, which is left alone. A, B, C are degrees about Z, Y′, X″; S and T are kept as
// written (decimal or 'B…').
#include <array>
#include <cstdlib>
#include <map>

#include "scan.hpp"
#include "stepcal/common/units.hpp"

namespace stepcal::programs::detail {
namespace {

const std::array<const char*, 6> kPoseNames = {"x", "y", "z", "a", "b", "c"};
const std::array<const char*, 6> kAxisNames = {"a1", "a2", "a3", "a4", "a5", "a6"};

bool isMotionKeyword(const std::string& w) {
  return w == "ptp" || w == "lin" || w == "circ" || w == "spl" || w == "slin" || w == "scirc" ||
         w == "sptp";
}

bool isRelativeMotion(const std::string& w) {
  return w == "ptp_rel" || w == "lin_rel" || w == "circ_rel" || w == "sptp_rel" ||
         w == "slin_rel" || w == "scirc_rel" || w == "spl_rel";
}

/// An aggregate's items: each name (lower case) with its number's field where it is one.
struct Aggregate {
  size_t begin = 0;
  std::map<std::string, std::pair<NumberField, double>> numbers;
  std::map<std::string, std::string> words;  ///< S/T and other non-numbers as written
  std::vector<std::pair<std::string, Aggregate>> nested;  ///< {M 30, CM {X 0, …}}: CM's
  const Aggregate* nestedNamed(const std::string& name) const {
    for (const auto& [n, a] : nested) {
      if (n == name) return &a;
    }
    return nullptr;
  }
  bool pose() const { return numbers.count("x") || numbers.count("y") || numbers.count("z") || numbers.count("c"); }
  bool axes() const { return numbers.count("a1") > 0; }
};

class KrlReader {
 public:
  KrlReader(std::string_view text, const std::string& path) : s_(text, path) {
    program_.language = Language::kKrl;
    program_.orientation = Orientation::kZyxDeg;
    program_.file_units_per_m = 1000.0;
    program_.file_units_per_rad = 1.0 / kRadPerDeg;
  }

  Program read() {
    while (!s_.atEnd()) statement();
    requireEnd();
    return std::move(program_);
  }

 private:
  /// One line: its statement up to a comment; aggregates in it read as targets or frames.
  void statement() {
    s_.skipSpace();
    if (s_.atEnd()) return;
    const size_t start = s_.pos();
    if (s_.peek() == ';' || s_.peek() == '&') return skipLine();
    std::string first = lowerCase(s_.word());
    if (first == "global") first = lowerCase(s_.word());
    if (!first.empty()) last_word_ = first;
    reported_ = false;
    size_t name_start = start;
    declared_type_.clear();
    if (first == "decl") {
      declared_type_ = lowerCase(s_.word());
      s_.skipBlanks();
      name_start = s_.pos();
    }
    if (first == "bas") toolOrBaseNumber();
    if (isMotionKeyword(first)) motionArgument(first);
    rest(first, name_start);
  }

  /// BAS(#TOOL, n) and BAS(#BASE, n): TOOL_DATA[n] or BASE_DATA[n] current from here on.
  void toolOrBaseNumber() {
    const size_t start = s_.pos();
    if (s_.accept('(', false) && s_.accept('#', false)) {
      const std::string kind = lowerCase(s_.word());
      if ((kind == "tool" || kind == "base") && s_.accept(',', false)) {
        const double n = s_.number("BAS's tool or base number", nullptr, false);
        const std::string name = (kind == "tool" ? "TOOL_DATA[" : "BASE_DATA[") + formatNumber(n) + "]";
        (kind == "tool" ? current_tool_ : current_base_) = frameIndex(name);
        // BAS selects the tool's load with it; tool 0, the flange, carries none.
        if (kind == "tool") current_load_ = long(n) == 0 ? -1 : loadIndex(program_, "LOAD_DATA[" + formatNumber(n) + "]");
      }
    }
    s_.seek(start);
  }

  static std::string formatNumber(double n) { return std::to_string(long(n)); }

  /// The rest of the line: aggregates, strings, brackets; ends at a comment or the line end.
  void rest(const std::string& first, size_t name_start) {
    const size_t start = s_.pos();
    int depth = 0;
    while (!s_.atEnd()) {
      const char c = s_.peek();
      if (c == '\n') break;
      if (c == ';') {
        skipLine();
        break;
      }
      if (c == '"' || c == '\'') {
        quoted(c);
      } else if (c == '{') {
        aggregateInStatement(first, assignedName(name_start));
      } else if (c == '=' && depth == 0) {
        s_.advance();
        currentFrameByName(assignedName(name_start));
      } else if (c == '(' || c == '[') {
        ++depth;
        s_.advance();
      } else if (c == ')' || c == ']' || c == '}') {
        if (c == '}' || --depth < 0) s_.fail("an unmatched '" + std::string(1, c) + "'");
        s_.advance();
      } else {
        s_.advance();
      }
    }
    if (depth != 0) s_.failAt(start, "an unclosed bracket in this statement");
  }

  /// The variable a statement assigns to (XP1, $BASE, TOOL_DATA[2]), upper case; empty when
  /// there is no '=' before the cursor.
  std::string assignedName(size_t name_start) const {
    const std::string_view before = s_.text().substr(name_start, s_.pos() - name_start);
    size_t eq = before.find('=');
    if (eq == std::string_view::npos) return "";
    std::string n(before.substr(0, eq));
    while (!n.empty() && (n.back() == ' ' || n.back() == '\t')) n.pop_back();
    for (char& c : n) c = char(std::toupper(static_cast<unsigned char>(c)));
    return n;
  }

  /// $TOOL = TOOL_DATA[n], $BASE = BASE_DATA[n], $LOAD = LOAD_DATA[n]: that frame or load
  /// current from here on.
  void currentFrameByName(const std::string& lhs) {
    if (lhs == "$LOAD") return currentLoadByName();
    if (lhs.rfind("$LOAD.", 0) == 0) {  // $LOAD.M = $DEF_L_M: the values are the controller's
      current_load_ = loadIndex(program_, "$LOAD line " + std::to_string(s_.line()));
      program_.loads[size_t(current_load_)].without_values = "components assigned one by one ($LOAD.M, $LOAD.CM …)";
      return;
    }
    if (lhs != "$TOOL" && lhs != "$BASE") return;
    const size_t start = s_.pos();
    const std::string_view name = s_.word();
    if (!name.empty() && s_.peek() == '[') {
      s_.advance();
      const double n = s_.number("a tool or base number", nullptr, false);
      if (s_.accept(']', false)) {
        const std::string frame = lowerCase(name) == "tool_data"   ? "TOOL_DATA[" + formatNumber(n) + "]"
                                  : lowerCase(name) == "base_data" ? "BASE_DATA[" + formatNumber(n) + "]"
                                                                   : "";
        if (!frame.empty()) (lhs == "$TOOL" ? current_tool_ : current_base_) = frameIndex(frame);
      }
    }
    s_.seek(start);
  }

  /// $LOAD = LOAD_DATA[n] (or any other name: a load whose values the command line gives) from
  /// here on; an inline {M …} is read as an aggregate.
  void currentLoadByName() {
    const size_t start = s_.pos();
    s_.skipBlanks();
    if (s_.peek() == '{') return s_.seek(start);
    std::string_view rest = s_.restOfLine();
    rest = rest.substr(0, rest.find(';'));
    while (!rest.empty() && (rest.back() == ' ' || rest.back() == '\t' || rest.back() == '\r')) rest.remove_suffix(1);
    std::string name;
    for (const char c : rest) {
      if (c != ' ' && c != '\t') name += char(std::toupper(static_cast<unsigned char>(c)));
    }
    if (name.rfind("LOAD_DATA[", 0) == 0 && name.back() == ']') {
      name = "LOAD_DATA[" + formatNumber(std::atof(name.c_str() + 10)) + "]";
    }
    if (!name.empty()) current_load_ = loadIndex(program_, name);
    s_.seek(start);
  }

  void skipLine() {
    while (!s_.atEnd() && s_.peek() != '\n') s_.advance();
  }

  /// A motion's first argument when it is not a literal nor a declared point: a point computed
  /// at run time (XP1:{X 10}, $POS_ACT, P[3]), reported.
  void motionArgument(const std::string& keyword) {
    s_.skipBlanks();
    if (s_.peek() == '{') return;
    const size_t start = s_.pos();
    std::string_view rest = s_.restOfLine();
    rest = rest.substr(0, rest.find(';'));
    const std::string_view name = s_.word();
    s_.skipBlanks();
    const char next = s_.peek();
    const bool plain = !name.empty() && name[0] != '$' && next != ':' && next != '(' && next != '[' && next != '.';
    if (!plain) {
      program_.not_literals.push_back({s_.lineOf(start), s_.columnOf(start),
                                       keyword + " " + std::string(rest)});
      reported_ = true;
    }
    s_.seek(start);
  }

  void quoted(char quote) {
    const size_t start = s_.pos();
    s_.advance();
    while (!s_.atEnd() && s_.peek() != quote && s_.peek() != '\n') s_.advance();
    if (s_.peek() != quote) s_.failAt(start, "a string that does not end on its line");
    s_.advance();
  }

  void aggregateInStatement(const std::string& first, const std::string& assigned) {
    const size_t start = s_.pos();
    const int line = s_.line(), column = s_.column();
    const Aggregate a = aggregate();
    if (assigned == "$LOAD" || assigned.rfind("LOAD_DATA[", 0) == 0 || declared_type_ == "load") {
      return load(a, start, assigned);
    }
    if ((!a.pose() && !a.axes()) || reported_) return;
    const bool tool = assigned == "$TOOL" || assigned.rfind("TOOL_DATA[", 0) == 0;
    const bool base = assigned == "$BASE" || assigned.rfind("BASE_DATA[", 0) == 0;
    if (isRelativeMotion(first)) {
      program_.not_literals.push_back({line, column, first + " (a move relative to where the robot is)"});
      return;
    }
    if (tool || base) return frame(a, start, assigned);
    if (!complete(a)) {
      program_.not_literals.push_back({line, column, "a partial aggregate: its other components are taken at run time"});
      return;
    }
    Target t = a.axes() ? joints(a, line, column) : pose(a, line, column);
    if (!isMotionKeyword(first)) t.name = assigned;
    t.tool = current_tool_;
    t.base = current_base_;
    t.load = current_load_;
    program_.targets.push_back(std::move(t));
  }

  /// $LOAD/LOAD_DATA[n]/DECL LOAD name = {M …, CM {X …, Y …, Z …, A …, B …, C …}, J {…}}: a
  /// load (mass kg, centre of gravity mm in the flange frame), current from here on when it is
  /// $LOAD. M −1 is KUKA's default load of the robot type, whose values no program holds.
  void load(const Aggregate& a, size_t start, const std::string& assigned) {
    const auto m = a.numbers.find("m");
    if (m == a.numbers.end()) s_.failAt(start, "a load without M; expected {M kg, CM {X mm, Y mm, Z mm, A, B, C}, J {…}}");
    const Aggregate* cm = a.nestedNamed("cm");
    for (const char* axis : {"x", "y", "z"}) {
      if (cm && !cm->numbers.count(axis)) s_.failAt(cm->begin, std::string("a load's CM without ") + char(axis[0] - 32) + "; expected CM {X mm, Y mm, Z mm, A, B, C}");
    }
    // An inline $LOAD is a load of its own at each assignment.
    const std::string name = assigned == "$LOAD" ? "$LOAD line " + std::to_string(s_.lineOf(start)) : assigned;
    const int index = loadIndex(program_, name);
    Load& l = program_.loads[size_t(index)];
    l.mass_kg.reset();
    l.without_values.clear();
    if (m->second.second < 0.0) {
      l.without_values = "M " + std::string(s_.text().substr(m->second.first.begin, m->second.first.end - m->second.first.begin)) +
                         " (KUKA's default load of the robot type, whose values the program does not hold)";
    } else {
      l.mass_kg = m->second.second;
      if (cm) l.p_CoG_m = Vec3(cm->numbers.at("x").second, cm->numbers.at("y").second, cm->numbers.at("z").second) / 1000.0;
    }
    if (assigned == "$LOAD") current_load_ = index;
  }

  bool complete(const Aggregate& a) const {
    const auto& names = a.axes() ? kAxisNames : kPoseNames;
    for (const char* n : names) {
      if (!a.numbers.count(n)) return false;
    }
    return true;
  }

  Target pose(const Aggregate& a, int line, int column) {
    std::vector<NumberField> fields;
    std::vector<double> written;
    for (const char* n : kPoseNames) {
      fields.push_back(a.numbers.at(n).first);
      written.push_back(a.numbers.at(n).second);
    }
    Target t = cartesianTarget(program_, fields, written, line, column);
    for (const char* n : {"s", "t"}) {
      if (a.words.count(n)) t.configuration += std::string(t.configuration.empty() ? "" : " ") + char(n[0] - 32) + " " + a.words.at(n);
    }
    return t;
  }

  Target joints(const Aggregate& a, int line, int column) {
    std::vector<NumberField> fields;
    std::vector<double> written;
    for (const char* n : kAxisNames) {
      fields.push_back(a.numbers.at(n).first);
      written.push_back(a.numbers.at(n).second);
    }
    return jointTarget(program_, fields, written, line, column);
  }

  /// $TOOL/$BASE/TOOL_DATA[n]/BASE_DATA[n] = {FRAME: …}: a frame, current from here on when it
  /// is $TOOL or $BASE.
  void frame(const Aggregate& a, size_t start, const std::string& name) {
    if (!complete(a) || a.axes()) s_.failAt(start, "a tool or base frame without all of X, Y, Z, A, B, C");
    std::vector<double> w;
    for (const char* n : kPoseNames) w.push_back(a.numbers.at(n).second);
    const int index = frameIndex(name);
    program_.frames[size_t(index)].X = poseFromWritten(w, Orientation::kZyxDeg, 1000.0);
    if (name == "$TOOL") current_tool_ = index;
    if (name == "$BASE") current_base_ = index;
  }

  int frameIndex(const std::string& name) {
    for (size_t i = 0; i < program_.frames.size(); ++i) {
      if (program_.frames[i].name == name) return int(i);
    }
    Frame f{name, std::nullopt};
    // Tool 0 is the flange, base 0 the world (taken as the robot's base: $WORLD = $ROBROOT).
    if (name == "TOOL_DATA[0]" || name == "BASE_DATA[0]") f.X = Pose::Identity();
    program_.frames.push_back(f);
    return int(program_.frames.size() - 1);
  }

  Aggregate aggregate() {
    Aggregate a;
    a.begin = s_.pos();
    s_.expect('{', "an aggregate");
    s_.skipBlanks();
    const size_t after_brace = s_.pos();
    const std::string_view type = s_.word();  // {E6POS: …}, {FRAME: …}
    if (type.empty() || !s_.accept(':', false)) s_.seek(after_brace);
    if (s_.accept('}', false)) return a;
    do {
      const std::string name = lowerCase(s_.word());
      if (name.empty()) s_.fail("'" + std::string(s_.restOfLine().substr(0, 20)) + "' in an aggregate; expected a component's name");
      s_.skipBlanks();
      const char c = s_.peek();
      if (c == '{') {
        a.nested.emplace_back(name, aggregate());
      } else if (c == '\'' || c == '"') {
        const size_t v = s_.pos();
        quoted(c);
        a.words[name] = std::string(s_.text().substr(v, s_.pos() - v));
      } else if (c == '#' || std::isalpha(static_cast<unsigned char>(c))) {
        if (c == '#') s_.advance();
        if (s_.word().empty()) s_.fail("an empty enumeration value in an aggregate");
      } else {
        NumberField f;
        const size_t at = s_.pos();
        const double value = s_.number("an aggregate's component", &f, false);
        if (a.numbers.count(name)) s_.failAt(at, "'" + name + "' twice in an aggregate");
        a.numbers[name] = {f, value};
        if (name == "s" || name == "t") a.words[name] = std::string(s_.text().substr(f.begin, f.end - f.begin));
      }
    } while (s_.accept(',', false));
    if (s_.atEnd()) s_.failAt(a.begin, "an aggregate that the file ends in; expected '}'");
    s_.expect('}', "an aggregate", false);
    return a;
  }

  /// A .src ends with END (or ENDFCT), a .dat with ENDDAT: a file cut short is refused.
  void requireEnd() {
    const std::string w = last_word_;
    if (w != "end" && w != "endfct" && w != "enddat") {
      s_.failAt(s_.text().size(), "the file ends without END or ENDDAT (after '" + w +
                                      "'): a truncated program, or not KRL");
    }
  }

  Scanner s_;
  Program program_;
  int current_tool_ = -1, current_base_ = -1, current_load_ = -1;
  std::string last_word_;
  std::string declared_type_;  ///< DECL's type (lower case) on this statement; empty else
  bool reported_ = false;  ///< the statement's motion is already reported as not a literal
};

}  // namespace

Program readKrl(std::string_view text, const std::string& path) {
  return KrlReader(text, path).read();
}

}  // namespace stepcal::programs::detail
