// ABB RAPID (.mod, .prg, .sys): robtarget literals [[x,y,z],[q1,q2,q3,q4],[cf1,cf4,cf6,cfx],
// [e1,…,e6]] declared (CONST/PERS/VAR robtarget p10 := […];), assigned, or inline in
// MoveJ/MoveL/MoveC (and their DO/Sync forms); jointtarget [[j1,…,j6],[e1,…,e6]] declared or in
// MoveAbsJ; tooldata and wobjdata declarations as frames, loaddata as loads. A Move's tool is
// its positional argument after the zone, its work object \WObj:=…, its total load \TLoad:=…
// (in place of the tool's load); GripLoad's payload (in the tool frame) is added to the tool's
// load of the Moves after it; a declared target takes those of the first Move that uses it. Keywords in any case; '!' starts a comment, left alone; 9E9 and
// 9E+09 mark unused axes and are never rewritten. Positions in mm, the quaternion w, x, y, z.
#include <algorithm>
#include <map>
#include <set>

#include "scan.hpp"
#include "stepcal/common/units.hpp"

namespace stepcal::programs::detail {
namespace {

/// A literal as written: a list [a, b, …] or a scalar (a number, a word, a string).
struct Node {
  bool list = false, number = false;
  std::vector<Node> items;
  NumberField field;
  double value = 0.0;
  std::string word;  ///< a word or string as written
  size_t begin = 0, end = 0;
};

bool isNumbers(const Node& n, size_t count) {
  if (!n.list || n.items.size() != count) return false;
  for (const Node& i : n.items) {
    if (!i.number) return false;
  }
  return true;
}

bool isRobtarget(const Node& n) {
  return n.list && n.items.size() == 4 && isNumbers(n.items[0], 3) && isNumbers(n.items[1], 4) &&
         isNumbers(n.items[2], 4) && isNumbers(n.items[3], 6);
}

bool isJointtarget(const Node& n) {
  return n.list && n.items.size() == 2 && isNumbers(n.items[0], 6) && isNumbers(n.items[1], 6);
}

/// [[x,y,z],[q1..q4]] in mm as a pose, m.
bool isPose(const Node& n) { return n.list && n.items.size() == 2 && isNumbers(n.items[0], 3) && isNumbers(n.items[1], 4); }

Pose poseOf(const Node& n) {
  std::vector<double> w;
  for (const Node& k : n.items[0].items) w.push_back(k.value);
  for (const Node& k : n.items[1].items) w.push_back(k.value);
  return poseFromWritten(w, Orientation::kQuaternionWxyz, 1000.0);
}

bool isMove(const std::string& w) {
  return w == "movej" || w == "movel" || w == "movec" || w == "moveabsj" || w == "movejdo" ||
         w == "moveldo" || w == "movecdo" || w == "movejsync" || w == "movelsync" || w == "movecsync";
}

class RapidReader {
 public:
  RapidReader(std::string_view text, const std::string& path) : s_(text, path) {
    program_.language = Language::kRapid;
    program_.orientation = Orientation::kQuaternionWxyz;
    program_.file_units_per_m = 1000.0;
    program_.file_units_per_rad = 1.0 / kRadPerDeg;
  }

  Program read() {
    while (true) {
      s_.skipSpace();
      if (s_.atEnd()) break;
      token();
    }
    if (!ended_) {
      s_.failAt(s_.text().size(), "the file ends without ENDMODULE: a truncated module, or not RAPID");
    }
    return std::move(program_);
  }

 private:
  void token() {
    const char c = s_.peek();
    if (c == '!' || c == '%') return skipLine();
    if (c == '"') return quoted();
    if (c == '[') return strayLiteral();
    if (c == '(') ++parentheses_;
    if (c == ')') parentheses_ = std::max(0, parentheses_ - 1);
    if (!isWordChar(c)) return s_.advance();
    const size_t start = s_.pos();
    const std::string w = lowerCase(s_.word());
    if (ended_) s_.failAt(start, "'" + w + "' after ENDMODULE; expected the end of the file");
    if (w == "endmodule") {
      ended_ = true;
    } else if (isMove(w)) {
      move(w, start);
    } else if (w == "gripload") {
      gripLoad(start);
    } else if ((w == "const" || w == "pers" || w == "var") && parentheses_ == 0) {
      declaration();
    } else if (s_.skipBlanks(), s_.peek() == ':' && s_.peek(1) == '=') {
      assignment(std::string(s_.text().substr(start, s_.pos() - start)));
    }
  }

  void skipLine() {
    while (!s_.atEnd() && s_.peek() != '\n') s_.advance();
  }

  void quoted() {
    const size_t start = s_.pos();
    s_.advance();
    while (!s_.atEnd() && s_.peek() != '"' && s_.peek() != '\n') s_.advance();
    if (s_.peek() != '"') s_.failAt(start, "a string that does not end on its line");
    s_.advance();
  }

  Node literal() {
    s_.skipSpace();
    Node n;
    n.begin = s_.pos();
    if (s_.peek() == '[') {
      n.list = true;
      s_.advance();
      do {
        n.items.push_back(literal());
      } while (s_.accept(','));
      if (s_.atEnd()) s_.failAt(n.begin, "a list that the file ends in; expected ']'");
      s_.expect(']', "a list");
    } else if (s_.peek() == '"') {
      quoted();
      n.word = std::string(s_.text().substr(n.begin, s_.pos() - n.begin));
    } else {
      const std::string_view item = itemText();
      if (isNumberText(item)) {
        n.number = true;
        n.value = s_.number("a literal", &n.field);
      } else {
        n.word = std::string(item);  // a name (TRUE, tool0) or an expression (message.joints)
        s_.seek(n.begin + item.size());
      }
    }
    n.end = s_.pos();
    return n;
  }

  /// A list item's text: up to the ',' or ']' that ends it (brackets and strings inside read
  /// whole), without trailing blanks.
  std::string_view itemText() const {
    const std::string_view text = s_.text();
    size_t at = s_.pos(), end = at;
    int depth = 0;
    while (at < text.size()) {
      const char c = text[at];
      if (depth == 0 && (c == ',' || c == ']' || c == ';' || c == '\n')) break;
      if (c == '(' || c == '[') ++depth;
      if (c == ')' || c == ']') --depth;
      if (c == '"') {
        const size_t close = text.find('"', at + 1);
        at = close == std::string_view::npos ? text.size() : close;
      }
      ++at;
      if (c != ' ' && c != '\t' && c != '\r') end = at;
    }
    return text.substr(s_.pos(), end - s_.pos());
  }

  static bool isNumberText(std::string_view t) {
    size_t i = (!t.empty() && (t[0] == '-' || t[0] == '+')) ? 1 : 0;
    const size_t digits = i;
    while (i < t.size() && (std::isdigit(static_cast<unsigned char>(t[i])) || t[i] == '.')) ++i;
    if (i == digits) return false;
    if (i < t.size() && (t[i] == 'e' || t[i] == 'E')) {
      ++i;
      if (i < t.size() && (t[i] == '+' || t[i] == '-')) ++i;
      while (i < t.size() && std::isdigit(static_cast<unsigned char>(t[i]))) ++i;
    }
    return i == t.size();
  }

  /// Whether a literal holds an expression (a name or a computation where a number goes).
  static bool holdsExpression(const Node& n) {
    if (!n.list) return !n.number && !n.word.empty() && n.word[0] != '"';
    for (const Node& i : n.items) {
      if (holdsExpression(i)) return true;
    }
    return false;
  }

  /// Everything up to the statement's ';' (strings and lists read whole).
  void toSemicolon(size_t start) {
    int depth = 0;
    while (true) {
      s_.skipSpace();
      if (s_.atEnd()) s_.failAt(start, "a statement that the file ends in; expected ';'");
      const char c = s_.peek();
      if (c == ';' && depth == 0) return s_.advance();
      if (c == '!') {
        skipLine();
      } else if (c == '"') {
        quoted();
      } else if (c == '[') {
        strayLiteral();
      } else {
        if (c == '(') ++depth;
        if (c == ')' && --depth < 0) s_.fail("an unmatched ')'");
        s_.advance();
      }
    }
  }

  /// A list outside a declaration or a Move: a robtarget there (passed to a procedure) is
  /// reported, not corrected.
  void strayLiteral() {
    const int line = s_.line(), column = s_.column();
    const Node n = literal();
    if (isRobtarget(n)) {
      program_.not_literals.push_back({line, column, "a robtarget passed to an instruction that is not a Move"});
    }
  }

  Target robtarget(const Node& n, const std::string& name) {
    std::vector<NumberField> fields;
    std::vector<double> written;
    for (int k = 0; k < 2; ++k) {
      for (const Node& i : n.items[size_t(k)].items) {
        fields.push_back(i.field);
        written.push_back(i.value);
      }
    }
    Target t = cartesianTarget(program_, fields, written, s_.lineOf(n.begin), s_.columnOf(n.begin));
    t.configuration = std::string(s_.text().substr(n.items[2].begin, n.items[2].end - n.items[2].begin));
    t.name = name;
    return t;
  }

  Target jointtarget(const Node& n, const std::string& name) {
    std::vector<NumberField> fields;
    std::vector<double> written;
    for (const Node& i : n.items[0].items) {
      fields.push_back(i.field);
      written.push_back(i.value);
    }
    Target t = jointTarget(program_, fields, written, s_.lineOf(n.begin), s_.columnOf(n.begin));
    t.name = name;
    return t;
  }

  /// CONST/PERS/VAR type name[{n}] [:= value];
  void declaration() {
    const size_t start = s_.pos();
    const std::string type = lowerCase(s_.word());
    const std::string name(s_.word());
    if (type.empty() || name.empty()) s_.failAt(start, "a declaration without its type and name");
    s_.skipBlanks();
    if (s_.peek() == '{') {
      while (!s_.atEnd() && s_.peek() != '}' && s_.peek() != '\n') s_.advance();
      s_.expect('}', "an array's size", false);
    }
    if (type == "robtarget" || type == "jointtarget") declared_.insert(lowerCase(name));
    if (!s_.accept(':', false)) return toSemicolon(start);
    s_.expect('=', "a declaration");
    s_.skipSpace();
    if (s_.peek() != '[') {
      if (type == "robtarget" || type == "jointtarget") {
        program_.not_literals.push_back({s_.line(), s_.column(), name + " := " + std::string(s_.restOfLine())});
      }
      return toSemicolon(start);
    }
    const Node value = literal();
    declared(type, name, value);
    s_.expect(';', "a declaration");
  }

  void declared(const std::string& type, const std::string& name, const Node& value) {
    if ((type == "robtarget" || type == "jointtarget") && holdsExpression(value)) {
      program_.not_literals.push_back({s_.lineOf(value.begin), s_.columnOf(value.begin), name + " := a value computed from names"});
      return;
    }
    if (type == "robtarget" || type == "jointtarget") {
      const bool robot = type == "robtarget";
      const bool one = robot ? isRobtarget(value) : isJointtarget(value);
      if (one) return addNamed(robot ? robtarget(value, name) : jointtarget(value, name));
      for (size_t i = 0; i < value.items.size(); ++i) {
        const Node& e = value.items[i];
        if (!(robot ? isRobtarget(e) : isJointtarget(e))) {
          s_.failAt(e.begin, "a " + type + " whose value is not one; expected " +
                                 (robot ? "[[x,y,z],[q1,q2,q3,q4],[cf1,cf4,cf6,cfx],[e1,…,e6]]"
                                        : "[[j1,…,j6],[e1,…,e6]]"));
        }
        addNamed(robot ? robtarget(e, name + "{" + std::to_string(i + 1) + "}")
                       : jointtarget(e, name + "{" + std::to_string(i + 1) + "}"));
      }
    } else if (type == "tooldata") {
      tool(name, value);
    } else if (type == "wobjdata") {
      workObject(name, value);
    } else if (type == "loaddata") {
      if (value.items.empty() || !value.items[0].number || value.items.size() < 2 || !isNumbers(value.items[1], 3)) {
        s_.failAt(value.begin, "loaddata " + name + ": expected [mass,[x,y,z],[q1..q4],ix,iy,iz]");
      }
      Load& l = program_.loads[size_t(loadIndex(program_, name, true))];
      l.mass_kg = value.items[0].value;
      for (int a = 0; a < 3; ++a) l.p_CoG_m[a] = value.items[1].items[size_t(a)].value / 1000.0;
    }
  }

  /// tooldata [robhold, [[x,y,z],[q]], [mass, [cog], [aom], ix, iy, iz]].
  void tool(const std::string& name, const Node& value) {
    if (!(value.list && value.items.size() == 3 && isPose(value.items[1]) && value.items[2].list &&
          value.items[2].items.size() >= 2 && value.items[2].items[0].number && isNumbers(value.items[2].items[1], 3))) {
      s_.failAt(value.begin, "tooldata " + name + ": expected [robhold,[[x,y,z],[q1..q4]],[mass,[x,y,z],[q1..q4],ix,iy,iz]]");
    }
    if (lowerCase(value.items[0].word) != "true") {
      s_.failAt(value.begin, "tooldata " + name + ": a stationary tool (robhold FALSE); only a tool the robot holds is corrected");
    }
    Frame f{name, poseOf(value.items[1]), value.items[2].items[0].value, Vec3::Zero()};
    for (int a = 0; a < 3; ++a) f.p_CoG_m[a] = value.items[2].items[1].items[size_t(a)].value / 1000.0;
    setFrame(f);
  }

  /// wobjdata [robhold, ufprog, ufmec, [[uframe]], [[oframe]]]: the object frame in the base.
  void workObject(const std::string& name, const Node& value) {
    if (!(value.list && value.items.size() == 5 && isPose(value.items[3]) && isPose(value.items[4]))) {
      s_.failAt(value.begin, "wobjdata " + name + ": expected [robhold,ufprog,\"ufmec\",[[x,y,z],[q1..q4]],[[x,y,z],[q1..q4]]]");
    }
    if (lowerCase(value.items[0].word) != "false" || lowerCase(value.items[1].word) != "true") {
      s_.failAt(value.begin, "wobjdata " + name + ": a work object held by the robot or moved by a mechanical unit; only a fixed one is corrected");
    }
    setFrame(Frame{name, poseOf(value.items[3]) * poseOf(value.items[4])});
  }

  void setFrame(const Frame& f) {
    const int i = frameIndex(f.name);
    program_.frames[size_t(i)] = f;
  }

  int frameIndex(const std::string& name) {
    for (size_t i = 0; i < program_.frames.size(); ++i) {
      if (equalsIgnoringCase(program_.frames[i].name, name)) return int(i);
    }
    Frame f{name, std::nullopt};
    if (equalsIgnoringCase(name, "tool0") || equalsIgnoringCase(name, "wobj0")) f.X = Pose::Identity();
    program_.frames.push_back(f);
    return int(program_.frames.size() - 1);
  }

  void addNamed(Target t) {
    named_[lowerCase(t.name)] = program_.targets.size();
    program_.targets.push_back(std::move(t));
  }

  /// name := [...];
  void assignment(const std::string& name) {
    const size_t start = s_.pos();
    s_.advance(2);
    s_.skipSpace();
    if (s_.peek() != '[') return toSemicolon(start);
    const Node value = literal();
    if (isRobtarget(value)) addNamed(robtarget(value, name));
    s_.expect(';', "an assignment");
  }

  struct Argument {
    size_t begin = 0;
    std::string text;           ///< as written
    std::optional<Node> value;  ///< a literal list
  };

  /// The Move's arguments up to ';': positional ones and \\Name:=value ones, each as written.
  std::vector<Argument> arguments(size_t start) {
    std::vector<Argument> args;
    int depth = 0;
    bool open = false;
    size_t end = 0;
    const auto close = [&] {
      if (open) args.back().text = std::string(s_.text().substr(args.back().begin, end - args.back().begin));
      open = false;
    };
    while (true) {
      s_.skipSpace();
      if (s_.atEnd()) s_.failAt(start, "a Move that the file ends in; expected ';'");
      const char c = s_.peek();
      if ((c == ';' || c == ',') && depth == 0) {
        if (!open) s_.fail("an empty argument; expected a value before '" + std::string(1, c) + "'");
        close();
        s_.advance();
        if (c == ';') break;
        continue;
      }
      if (c == '!') {
        skipLine();
        continue;
      }
      if (!open) {
        args.push_back(Argument{s_.pos(), "", std::nullopt});
        open = true;
        if (c == '[') {
          args.back().value = literal();
          end = s_.pos();
          continue;
        }
      }
      if (c == '"') {
        quoted();
      } else {
        if (c == '(' || c == '[') ++depth;
        if ((c == ')' || c == ']') && --depth < 0) s_.fail("an unmatched '" + std::string(1, c) + "'");
        s_.advance();
      }
      end = s_.pos();
    }
    return args;
  }

  /// GripLoad name; (load0: none): the payload of the Moves after it.
  void gripLoad(size_t start) {
    const std::string name(s_.word());
    if (name.empty()) s_.failAt(start, "GripLoad without its loaddata; expected GripLoad name;");
    grip_load_ = equalsIgnoringCase(name, "load0") ? -1 : loadIndex(program_, name, true);
    toSemicolon(start);
  }

  /// MoveX [\Conc,] point(s), speed, zone, tool [\WObj:=w] [\TLoad:=l];
  void move(const std::string& keyword, size_t start) {
    std::vector<Argument> args = arguments(start);
    std::vector<const Argument*> positional;
    std::string wobj = "wobj0", tload = "load0";
    for (const Argument& a : args) {
      const std::string lower = lowerCase(a.text);
      const size_t w = lower.find("\\wobj:=");
      if (w != std::string::npos) wobj = wordAt(a.text, w + 7);
      const size_t l = lower.find("\\tload:=");
      if (l != std::string::npos) tload = wordAt(a.text, l + 8);
      if (a.text[0] != '\\') positional.push_back(&a);
    }
    // \TLoad:=load0 is no total load: the tool's own is used.
    const int load = equalsIgnoringCase(tload, "load0") ? -1 : loadIndex(program_, tload, true);
    const bool circular = keyword.rfind("movec", 0) == 0;
    const size_t points = circular ? 2 : 1;
    if (positional.size() < points + 3) {
      s_.failAt(start, keyword + " with " + std::to_string(positional.size()) +
                           " arguments; expected the point(s), speed, zone and tool");
    }
    const int tool = frameIndex(wordAt(positional[points + 2]->text, 0));
    const int base = frameIndex(wobj);
    for (size_t k = 0; k < points; ++k) point(keyword, *positional[k], tool, base, load);
  }

  static std::string wordAt(const std::string& text, size_t at) {
    size_t end = at;
    while (end < text.size() && (isWordChar(text[end]) || text[end] == '.')) ++end;
    return text.substr(at, end - at);
  }

  void point(const std::string& keyword, const Argument& a, int tool, int base, int load) {
    const bool joints = keyword == "moveabsj";
    if (a.value) {
      const bool fits = joints ? isJointtarget(*a.value) : isRobtarget(*a.value);
      if (!fits && holdsExpression(*a.value)) {
        program_.not_literals.push_back({s_.lineOf(a.begin), s_.columnOf(a.begin), keyword + " " + a.text});
        return;
      }
      if (!fits) {
        s_.failAt(a.begin, keyword + "'s target is not a " + (joints ? "jointtarget" : "robtarget") + " literal");
      }
      Target t = joints ? jointtarget(*a.value, "") : robtarget(*a.value, "");
      t.tool = tool;
      t.base = base;
      t.load = load;
      t.grip_load = grip_load_;
      program_.targets.push_back(std::move(t));
      return;
    }
    const std::string name = wordAt(a.text, a.text[0] == '*' ? 1 : 0);
    const auto found = named_.find(lowerCase(name));
    if (name.size() == a.text.size() && found != named_.end()) {
      Target& t = program_.targets[found->second];
      if (t.tool < 0) {
        t.tool = tool;
        t.base = base;
        t.load = load;
        t.grip_load = grip_load_;
      } else if (t.tool != tool || t.load != load || t.grip_load != grip_load_) {
        t.other_loads += std::string(t.other_loads.empty() ? "" : ", ") + "line " + std::to_string(s_.lineOf(a.begin)) +
                         " with another tool or load";
      }
      return;
    }
    const bool plain = name.size() == a.text.size();
    const std::string why = !plain ? "" : declared_.count(lowerCase(name)) ? " (its value is set at run time)"
                                                                         : " (declared in another module)";
    program_.not_literals.push_back({s_.lineOf(a.begin), s_.columnOf(a.begin), keyword + " " + a.text + why});
  }

  Scanner s_;
  Program program_;
  std::map<std::string, size_t> named_;
  std::set<std::string> declared_;  ///< every robtarget and jointtarget name, with a literal or not
  int parentheses_ = 0;             ///< inside a routine's parameter list: no declarations there
  int grip_load_ = -1;              ///< GripLoad's payload in force (an index into loads), -1 none
  bool ended_ = false;
};

}  // namespace

Program readRapid(std::string_view text, const std::string& path) {
  return RapidReader(text, path).read();
}

}  // namespace stepcal::programs::detail
