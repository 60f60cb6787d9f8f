// URScript (.script): pose literals p[x, y, z, rx, ry, rz] (m, rotation vector in rad) in
// movel/movej/movep/movec or assigned to a variable (global or local); joint lists [q1, …, q6]
// (rad) as the first argument of movej/movel/movep; set_tcp(p[…]) as the tool from there on,
// set_payload(m, [cx, cy, cz]) (and set_target_payload, set_payload_mass, set_payload_cog) as
// the load from there on.
// A pose inside any other call (pose_trans, pose_add,
// get_inverse_kin, …) is composed at run time: reported, not corrected. '#' starts a comment,
// left alone (poses in comments too). Blocks (def, if, while, for, thread … end) must close.
#include "scan.hpp"

namespace stepcal::programs::detail {
namespace {

bool isMove(const std::string& w) { return w == "movel" || w == "movej" || w == "movep" || w == "movec"; }

bool opensBlock(const std::string& w) {
  return w == "def" || w == "if" || w == "while" || w == "for" || w == "thread";
}

class UrReader {
 public:
  UrReader(std::string_view text, const std::string& path) : s_(text, path) {
    program_.language = Language::kUrScript;
    program_.orientation = Orientation::kRotationVector;
    program_.file_units_per_m = 1.0;
    program_.file_units_per_rad = 1.0;
  }

  Program read() {
    while (true) {
      s_.skipSpace();
      if (s_.atEnd()) break;
      line();
    }
    if (!blocks_.empty()) {
      s_.failAt(blocks_.back(), "a block that is never closed by 'end' (the file ends): a truncated script");
    }
    return std::move(program_);
  }

 private:
  struct Call {
    std::string name;  ///< lower case; empty for a bracket that is not a call
    int argument = 0;  ///< the argument being read, from 0
  };

  /// One line: its calls, brackets and literals; ends at a comment or the line end.
  void line() {
    const size_t start = s_.pos();
    std::string first = lowerCase(s_.word());
    if (first == "global" || first == "local") first = lowerCase(s_.word());
    if (opensBlock(first)) blocks_.push_back(start);
    if (first == "end") {
      if (blocks_.empty()) s_.failAt(start, "'end' without a block to close");
      blocks_.pop_back();
    }
    s_.seek(start);
    std::vector<Call> calls;
    std::string last_word;
    bool assigned = false;
    while (!s_.atEnd() && s_.peek() != '\n' && s_.peek() != '#') {
      const char c = s_.peek();
      if (isWordChar(c)) {
        const size_t w = s_.pos();
        last_word = lowerCase(s_.word());
        if (last_word == "p" && s_.peek() == '[') pose(w, calls, assigned);
        if (isPayloadCall(last_word) && s_.peek() == '(') payload(w, last_word);
        continue;
      }
      if (c == '"' || c == '\'') {
        quoted(c);
      } else if (c == '(') {
        calls.push_back({last_word, 0});
        s_.advance();
      } else if (c == '[') {
        list(calls);
        continue;
      } else if (c == ')') {
        if (calls.empty()) s_.fail("an unmatched ')'");
        calls.pop_back();
        s_.advance();
      } else if (c == ',') {
        if (!calls.empty()) ++calls.back().argument;
        s_.advance();
      } else {
        if (c == '=' && s_.peek(1) != '=' && calls.empty()) assigned = true;
        s_.advance();
      }
      if (!isWordChar(c)) last_word.clear();
    }
    if (!calls.empty()) s_.failAt(start, "an unclosed '(' on this line");
    while (!s_.atEnd() && s_.peek() != '\n') s_.advance();
  }

  void quoted(char quote) {
    const size_t start = s_.pos();
    s_.advance();
    while (!s_.atEnd() && s_.peek() != quote && s_.peek() != '\n') s_.advance();
    if (s_.peek() != quote) s_.failAt(start, "a string that does not end on its line");
    s_.advance();
  }

  /// [a, b, …] of numbers, on one line; empty fields when it holds anything else (then it is
  /// skipped whole).
  std::vector<NumberField> numbers(std::vector<double>& values) {
    const size_t start = s_.pos();
    s_.expect('[', "a list", false);
    std::vector<NumberField> fields;
    if (s_.accept(']', false)) return fields;
    bool plain = true;
    int depth = 1;
    while (depth > 0) {
      s_.skipBlanks();
      if (s_.atEnd() || s_.peek() == '\n' || s_.peek() == '#') s_.failAt(start, "a list that does not end on its line; expected ']'");
      const char c = s_.peek();
      if (plain && depth == 1 && (c == '-' || c == '+' || c == '.' || std::isdigit(static_cast<unsigned char>(c)))) {
        NumberField f;
        values.push_back(s_.number("a list", &f, false));
        fields.push_back(f);
        s_.skipBlanks();
        if (s_.peek() != ',' && s_.peek() != ']') plain = false;
        continue;
      }
      if (c == '[') ++depth;
      if (c == ']') --depth;
      if (c != ',' && c != ']') plain = false;
      s_.advance();
    }
    if (!plain) fields.clear();
    return fields;
  }

  void pose(size_t start, const std::vector<Call>& calls, bool assigned) {
    std::vector<double> values;
    const std::vector<NumberField> fields = numbers(values);
    const std::string call = calls.empty() ? "" : calls.back().name;
    if (fields.size() != 6) {
      if (call.empty() || isMove(call)) {
        program_.not_literals.push_back({s_.lineOf(start), s_.columnOf(start), "a pose that is not six numbers"});
      }
      return;
    }
    const bool outermost = calls.size() == 1 || (calls.empty() && assigned);
    if (call == "set_tcp" && calls.size() == 1) {
      program_.frames.push_back(Frame{"set_tcp line " + std::to_string(s_.lineOf(start)),
                                      poseFromWritten(values, Orientation::kRotationVector, 1.0)});
      current_tool_ = int(program_.frames.size() - 1);
      return;
    }
    if (outermost && (call.empty() || isMove(call))) {
      Target t = cartesianTarget(program_, fields, values, s_.lineOf(start), s_.columnOf(start));
      t.tool = current_tool_;
      t.load = current_load_;
      program_.targets.push_back(std::move(t));
      return;
    }
    program_.not_literals.push_back({s_.lineOf(start), s_.columnOf(start),
                                     "a pose inside " + (call.empty() ? std::string("an expression") : call + "(…)") +
                                         ": composed at run time"});
  }

  static bool isPayloadCall(const std::string& w) {
    return w == "set_payload" || w == "set_target_payload" || w == "set_payload_mass" || w == "set_payload_cog";
  }

  /// set_payload(m[, [cx, cy, cz]]) and set_target_payload(m, [cx, cy, cz], …) (kg, m from the
  /// flange; without the centre of gravity, the one in force stays, as UR's does),
  /// set_payload_mass(m), set_payload_cog([cx, cy, cz]): the load of the targets after it.
  /// Values computed at run time are reported: the targets after it keep the load before.
  void payload(size_t start, const std::string& call) {
    const size_t open = s_.pos();
    s_.advance();
    Load load{call + " line " + std::to_string(s_.lineOf(start)), 0.0, Vec3::Zero(), ""};
    if (current_load_ >= 0) load = Load{load.name, program_.loads[size_t(current_load_)].mass_kg,
                                        program_.loads[size_t(current_load_)].p_CoG_m, ""};
    bool literal = true;
    if (call != "set_payload_cog") {
      s_.skipBlanks();
      const char c = s_.peek();
      literal = c == '-' || c == '.' || std::isdigit(static_cast<unsigned char>(c));
      if (literal) load.mass_kg = s_.number("the payload's mass", nullptr, false);
      s_.skipBlanks();
      literal = literal && (call == "set_payload_mass" ? s_.peek() == ')' : s_.accept(',', false) || s_.peek() == ')');
    }
    if (literal && call != "set_payload_mass" && s_.peek() != ')') {
      std::vector<double> cog;
      s_.skipBlanks();
      literal = s_.peek() == '[' && numbers(cog).size() == 3;
      if (literal) load.p_CoG_m = Vec3(cog[0], cog[1], cog[2]);
      s_.skipBlanks();
      literal = literal && (s_.peek() == ')' || (call == "set_target_payload" && s_.peek() == ','));
    }
    s_.seek(open);
    if (!literal) {
      program_.not_literals.push_back({s_.lineOf(start), s_.columnOf(start),
                                       call + " with values computed at run time: the targets after it keep the load before"});
      return;
    }
    program_.loads.push_back(load);
    current_load_ = int(program_.loads.size() - 1);
  }

  /// A list: a movej/movel/movep's joint targets, or another list left alone.
  void list(const std::vector<Call>& calls) {
    const size_t start = s_.pos();
    std::vector<double> values;
    const std::vector<NumberField> fields = numbers(values);
    const std::string call = calls.empty() ? "" : calls.back().name;
    if (calls.size() == 1 && isMove(call) && calls.back().argument == 0 && fields.size() == 6) {
      Target t = jointTarget(program_, fields, values, s_.lineOf(start), s_.columnOf(start));
      t.tool = current_tool_;
      t.load = current_load_;
      program_.targets.push_back(std::move(t));
    }
  }

  Scanner s_;
  Program program_;
  std::vector<size_t> blocks_;
  int current_tool_ = -1, current_load_ = -1;
};

}  // namespace

Program readUrScript(std::string_view text, const std::string& path) {
  return UrReader(text, path).read();
}

}  // namespace stepcal::programs::detail
