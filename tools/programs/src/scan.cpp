#include "scan.hpp"

#include <algorithm>
#include <cctype>
#include <optional>

#include "stepcal/common/error.hpp"
#include "stepcal/common/text_number.hpp"
#include "stepcal/common/units.hpp"

namespace stepcal::programs::detail {

bool isWordChar(char c) {
  return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '$';
}

bool equalsIgnoringCase(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i) {
    if (std::tolower(static_cast<unsigned char>(a[i])) !=
        std::tolower(static_cast<unsigned char>(b[i]))) {
      return false;
    }
  }
  return true;
}

std::string lowerCase(std::string_view text) {
  std::string out(text);
  for (char& c : out) c = char(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

void requireText(std::string_view text, const std::string& path) {
  const size_t nul = text.find('\0');
  if (nul == std::string_view::npos) return;
  const Scanner s(text, path);
  s.failAt(nul, "a NUL byte; expected a program's text");
}

int Scanner::lineOf(size_t offset) const {
  return 1 + int(std::count(text_.begin(), text_.begin() + long(std::min(offset, text_.size())), '\n'));
}

int Scanner::columnOf(size_t offset) const {
  offset = std::min(offset, text_.size());
  if (offset == 0) return 1;
  const size_t line_start = offset == 0 ? 0 : text_.rfind('\n', offset - 1);
  return int(offset - (line_start == std::string_view::npos ? 0 : line_start + 1)) + 1;
}

void Scanner::skipBlanks() {
  while (!atEnd() && (peek() == ' ' || peek() == '\t')) advance();
}

void Scanner::skipSpace() {
  while (!atEnd() && (peek() == ' ' || peek() == '\t' || peek() == '\r' || peek() == '\n')) advance();
}

void Scanner::expect(char c, const char* context, bool across_lines) {
  if (accept(c, across_lines)) return;
  fail(std::string(atEnd() ? "the file ends" : "'" + std::string(1, peek()) + "'") + " in " +
       context + "; expected '" + std::string(1, c) + "'");
}

bool Scanner::accept(char c, bool across_lines) {
  across_lines ? skipSpace() : skipBlanks();
  if (peek() != c || atEnd()) return false;
  advance();
  return true;
}

std::string_view Scanner::word() {
  skipBlanks();
  const size_t start = pos_;
  while (!atEnd() && isWordChar(peek())) advance();
  return text_.substr(start, pos_ - start);
}

bool Scanner::acceptWord(std::string_view w) {
  skipBlanks();
  if (pos_ + w.size() > text_.size()) return false;
  if (!equalsIgnoringCase(text_.substr(pos_, w.size()), w)) return false;
  if (pos_ + w.size() < text_.size() && isWordChar(text_[pos_ + w.size()])) return false;
  advance(w.size());
  return true;
}

double Scanner::number(const char* context, NumberField* field, bool across_lines) {
  across_lines ? skipSpace() : skipBlanks();
  const size_t start = pos_;
  if (peek() == '-' || peek() == '+') advance();
  const size_t digits_start = pos_;
  while (std::isdigit(static_cast<unsigned char>(peek()))) advance();
  int decimals = 0;
  if (peek() == '.') {
    advance();
    while (std::isdigit(static_cast<unsigned char>(peek()))) {
      advance();
      ++decimals;
    }
  }
  if (pos_ == digits_start || (pos_ == digits_start + 1 && text_[digits_start] == '.')) {
    seek(start);
    fail(std::string(atEnd() ? "the file ends" : "'" + std::string(restOfLine().substr(0, 20)) + "'") +
         " in " + context + "; expected a number");
  }
  if (peek() == 'e' || peek() == 'E') {
    advance();
    if (peek() == '+' || peek() == '-') advance();
    const size_t exponent_start = pos_;
    while (std::isdigit(static_cast<unsigned char>(peek()))) advance();
    if (pos_ == exponent_start) failAt(start, "a number with an empty exponent in " + std::string(context));
  }
  if (isWordChar(peek())) failAt(start, "'" + std::string(restOfLine().substr(0, 20)) + "' in " + context + "; expected a number");
  // parseFinite takes no '+' and no leading '.', which the languages write.
  std::string normal(text_.substr(start, pos_ - start));
  if (!normal.empty() && normal[0] == '+') normal.erase(0, 1);
  const size_t dot = normal.find('.');
  if (dot == 0 || (dot == 1 && normal[0] == '-')) normal.insert(dot, "0");
  if (!normal.empty() && normal.back() == '.') normal.pop_back();
  const std::optional<double> value = parseFinite(normal);
  if (!value) failAt(start, inQuotes(text_.substr(start, pos_ - start)) + " in " + context + "; expected a finite number");
  if (field) *field = NumberField{start, pos_, decimals};
  return *value;
}

std::string_view Scanner::restOfLine() const {
  const size_t end = text_.find_first_of("\r\n", pos_);
  return text_.substr(pos_, (end == std::string_view::npos ? text_.size() : end) - pos_);
}

void Scanner::failAt(size_t offset, const std::string& what) const {
  throw InputError(what, path_, lineOf(offset), std::to_string(columnOf(offset)));
}

Mat3 rotationZyxDeg(double a_deg, double b_deg, double c_deg) {
  return (Eigen::AngleAxisd(a_deg * kRadPerDeg, Vec3::UnitZ()) *
          Eigen::AngleAxisd(b_deg * kRadPerDeg, Vec3::UnitY()) *
          Eigen::AngleAxisd(c_deg * kRadPerDeg, Vec3::UnitX()))
      .toRotationMatrix();
}

}  // namespace stepcal::programs::detail
