// Numbers in text files (see text_number.hpp).
#include "stepcal/common/text_number.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <limits>
#include <system_error>

namespace stepcal {

std::string inQuotes(std::string_view text) {
  const size_t line_end = text.find_first_of("\r\n");
  if (line_end == std::string_view::npos && text.size() <= kQuotedCharsMax) {
    return "'" + std::string(text) + "'";
  }
  size_t cut = std::min({line_end, text.size(), kQuotedExcerptChars});
  // Back off to a character boundary: UTF-8 continuation bytes are 10xxxxxx.
  while (cut > 0 && cut < text.size() && (static_cast<unsigned char>(text[cut]) & 0xC0) == 0x80) {
    --cut;
  }
  return "'" + std::string(text.substr(0, cut)) + "…' (" + std::to_string(text.size()) +
         " bytes)";
}

std::optional<double> parseFinite(std::string_view text) {
  double v = 0.0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, v);
  if (ec != std::errc() || ptr != end || !std::isfinite(v)) return std::nullopt;
  return v;
}

std::optional<double> parseFiniteShifted(std::string_view text, int decimal_shift) {
  const size_t e = text.find_first_of("eE");
  long long exponent = 0;
  if (e != std::string_view::npos) {
    std::string_view exp_text = text.substr(e + 1);
    if (!exp_text.empty() && exp_text.front() == '+') {
      exp_text.remove_prefix(1);
      if (!exp_text.empty() && exp_text.front() == '-') return std::nullopt;
    }
    const char* end = exp_text.data() + exp_text.size();
    const auto [ptr, ec] = std::from_chars(exp_text.data(), end, exponent);
    if (ec != std::errc() || ptr != end) return std::nullopt;
  }
  // Saturating: an exponent this far out over- or underflows either way.
  constexpr long long kMax = std::numeric_limits<long long>::max();
  constexpr long long kMin = std::numeric_limits<long long>::min();
  if (decimal_shift > 0 && exponent > kMax - decimal_shift) {
    exponent = kMax;
  } else if (decimal_shift < 0 && exponent < kMin - decimal_shift) {
    exponent = kMin;
  } else {
    exponent += decimal_shift;
  }
  return parseFinite(std::string(text.substr(0, e)) + "e" + std::to_string(exponent));
}

std::string formatShortest(double value) {
  std::array<char, 64> buf{};
  const auto r = std::to_chars(buf.data(), buf.data() + buf.size(), value);
  return std::string(buf.data(), r.ptr);
}

}  // namespace stepcal
