// Splitting text tables (measurements.csv, poses.csv, correction programs, the IPA series) into
// lines and fields. One end-of-file rule for every reader; each reader judges the lines itself
// (an empty line, a wrong field count) and words its own errors.
#pragma once

#include <string_view>
#include <vector>

namespace stepcal {

/// The lines of a text, without their terminators; the views point into text.
/// End-of-file rule: the last line's newline is optional, so "a\nb" and "a\nb\n" both give
/// {"a", "b"}; a second final newline is an empty last line ("a\n\n" gives {"a", ""}), which
/// measurements.csv, poses.csv and the IPA series refuse and a correction program skips. Line
/// ends may be "\r\n": one '\r' before the '\n' (or at the end of the text) is dropped. Empty
/// text gives no lines. NUL bytes and other characters are kept (a program refuses NUL).
/// Byte-order mark rule: a UTF-8 byte-order mark at the start of the text (what spreadsheets'
/// "CSV UTF-8" writes) is skipped, so that every table reader takes such a file alike.
std::vector<std::string_view> splitLines(std::string_view text);

/// The text without a UTF-8 byte-order mark at its start (splitLines's rule).
std::string_view withoutByteOrderMark(std::string_view text);

/// The fields of one line, split at every separator; the views point into line.
/// No quoting and no trimming: n separators give n + 1 fields, so "a,,b" has an empty middle
/// field, "a,b," an empty last field and "" one empty field.
std::vector<std::string_view> splitFields(std::string_view line, char separator = ',');

}  // namespace stepcal
