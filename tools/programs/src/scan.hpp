#pragma once
// The readers' shared scanner: a cursor over the program's text that knows its line and column,
// reads numbers as the robot languages write them (leading dot, 9E+09, a sign) with their spans,
// and fails with the file, line and column.
#include <string>
#include <string_view>
#include <vector>

#include "stepcal/programs/program.hpp"

namespace stepcal::programs::detail {

class Scanner {
 public:
  Scanner(std::string_view text, const std::string& path) : text_(text), path_(path) {}

  size_t pos() const { return pos_; }
  bool atEnd() const { return pos_ >= text_.size(); }
  char peek(size_t ahead = 0) const {
    return pos_ + ahead < text_.size() ? text_[pos_ + ahead] : '\0';
  }
  std::string_view text() const { return text_; }
  const std::string& path() const { return path_; }
  /// 1-based line and column of a byte offset.
  int lineOf(size_t offset) const;
  int columnOf(size_t offset) const;
  int line() const { return lineOf(pos_); }
  int column() const { return columnOf(pos_); }

  void advance(size_t n = 1) { pos_ = std::min(text_.size(), pos_ + n); }
  void seek(size_t offset) { pos_ = offset; }
  /// Skips spaces and tabs (not line ends).
  void skipBlanks();
  /// Skips spaces, tabs and line ends.
  void skipSpace();
  /// Consumes `c` after blanks (and line ends when `across_lines`), or fails naming what.
  void expect(char c, const char* context, bool across_lines = true);
  /// Consumes `c` after blanks if it is there.
  bool accept(char c, bool across_lines = true);
  /// Consumes a word (letters, digits, _ and $) after blanks, in its case; empty when none.
  std::string_view word();
  /// Consumes `w` (any case) as a whole word after blanks if it is there.
  bool acceptWord(std::string_view w);
  /// A number after blanks: its value and span. Fails with `context` when there is none.
  double number(const char* context, NumberField* field = nullptr, bool across_lines = true);
  /// The rest of the current line (without its line end), for messages.
  std::string_view restOfLine() const;

  [[noreturn]] void fail(const std::string& what) const { failAt(pos_, what); }
  [[noreturn]] void failAt(size_t offset, const std::string& what) const;

 private:
  std::string_view text_;
  const std::string& path_;
  size_t pos_ = 0;
};

bool equalsIgnoringCase(std::string_view a, std::string_view b);
std::string lowerCase(std::string_view text);
bool isWordChar(char c);

/// The program's text is refused if it holds a NUL byte (a binary file given for a program).
void requireText(std::string_view text, const std::string& path);

/// Rotation R = Rz(a)·Ry(b)·Rx(c), angles in degrees (KRL A,B,C; Fanuc R,P,W).
Mat3 rotationZyxDeg(double a_deg, double b_deg, double c_deg);

/// A Cartesian target's pose from its numbers as written (position, then the orientation's 3
/// or 4), in SI.
Pose poseFromWritten(const std::vector<double>& written, Orientation orientation,
                     double file_units_per_m);

/// A literal's numbers as a target; the pose or joints converted from them.
Target cartesianTarget(const Program& program, std::vector<NumberField> fields,
                       std::vector<double> written, int line, int column);
Target jointTarget(const Program& program, std::vector<NumberField> fields,
                   std::vector<double> written, int line, int column);

}  // namespace stepcal::programs::detail
