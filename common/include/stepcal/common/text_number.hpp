// Numbers in text files: exact parsing and shortest formatting of doubles, for readers and
// writers of measurement files, plus quoting of values in messages.
#pragma once

#include <optional>
#include <string>
#include <string_view>

namespace stepcal {

/// The text in single quotes, for messages: 'text'.
/// Nothing is escaped; an empty text gives ''. A message is read by a person, so a long text is
/// cut: one with a line break or more than kQuotedCharsMax bytes gives its first line's first
/// bytes (whole UTF-8 characters) and its size, 'seq,pose_id,…' (438123 bytes).
std::string inQuotes(std::string_view text);
/// Longest text inQuotes gives whole: a value or a path, not a file's content.
constexpr size_t kQuotedCharsMax = 160;
/// What inQuotes keeps of a text it cuts.
constexpr size_t kQuotedExcerptChars = 40;

/// The whole text as a finite double, or nullopt.
/// Decimal point '.', optional exponent (e/E, sign allowed after it), optional leading '-'; no
/// leading '+', no spaces, no hex. Refuses empty text, trailing characters, nan, inf and values
/// out of the range of double. Correctly rounded, so "-0" gives -0.0.
std::optional<double> parseFinite(std::string_view text);

/// The whole decimal text times 10^decimal_shift as a finite double, or nullopt.
/// The shift moves the decimal point (it is added to the text's exponent) instead of
/// multiplying, so the value is rounded once, from its exact decimal: e.g. millimetre text
/// "1000.5" with shift -3 gives exactly the double nearest 1.0005 (metres), and every shortest
/// double text comes back bit-exactly. Accepts and refuses what parseFinite does (also "e+-3").
std::optional<double> parseFiniteShifted(std::string_view text, int decimal_shift);

/// The shortest text that parseFinite reads back to exactly value.
/// As std::to_chars writes it ("0.1", "-0", "1e+300"); "nan", "-nan", "inf" or "-inf" when
/// the value is not finite.
std::string formatShortest(double value);

}  // namespace stepcal
