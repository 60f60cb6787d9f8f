// What every HTML report page shares: escaping, number cells, the head with its style sheet and
// the page's end with its self-check (internal to stepcal::report).
#pragma once

#include <string>
#include <string_view>

#include "stepcal/common/units.hpp"

namespace stepcal::report::html {

inline constexpr double kMicro = 1e6;  ///< rad → µrad, 1 → ppm

/// Text made safe for HTML element content and attribute values.
std::string escape(std::string_view text);

/// A number for a table cell; "–" when it is not finite (no orientation measured).
std::string cell(const char* fmt, double value);

/// "20 kg".
std::string loadLabel(double load_kg);

/// The page's head and the opening of its body, with the reports' style sheet.
std::string pageHead(const std::string& title);

/// The page's end. Its one inline script checks, once the page has loaded, that every chart
/// (svg.chart) draws at least one data mark (.mark) inside its plot frame, and writes the result
/// into <pre id="report-check" hidden>: "ok: N charts with data", or "external files: …" when the
/// page refers to or loaded any file, or "empty charts: …"; with the page's height in
/// data-page-height (for a full-page screenshot). Nothing is fetched.
std::string pageEnd();

}  // namespace stepcal::report::html
