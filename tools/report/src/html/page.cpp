#include "stepcal/report/html/page.hpp"

#include <cmath>
#include <sstream>

#include "stepcal/report/text_format.hpp"

namespace stepcal::report::html {

std::string escape(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&#39;"; break;
      default: out += c;
    }
  }
  return out;
}

std::string cell(const char* fmt, double value) {
  return std::isfinite(value) ? format(fmt, value) : "&#8211;";
}

std::string loadLabel(double load_kg) { return format("%g kg", load_kg); }

std::string pageHead(const std::string& title) {
  std::ostringstream out;
  out << "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>"
      << escape(title) << "</title>\n<style>\n"
      << "body{font:14px/1.45 system-ui,-apple-system,'Segoe UI',sans-serif;color:#222;max-width:1360px;"
            "margin:20px auto;padding:0 16px}\n"
            "h1{font-size:22px;margin:0 0 8px}h2{font-size:18px;margin:30px 0 8px;padding-bottom:3px;"
            "border-bottom:1px solid #ddd}\n"
            "nav a{margin-right:12px}p{max-width:1000px}\n"
            "table{border-collapse:collapse;font-variant-numeric:tabular-nums;margin:6px 0}\n"
            "th,td{padding:3px 9px;border-bottom:1px solid #eee;text-align:right}"
            "th{background:#f5f5f5;font-weight:600}.l{text-align:left}\n"
            "table.dense{font-size:12.5px}.dense th,.dense td{padding:2px 5px}.dense td{white-space:nowrap}"
            ".dense .g{border-left:1px solid #ddd}"
            ".dense tr.validation td{background:#f4f8fc}\n"
            ".muted{color:#999}.item{white-space:nowrap}.sw{display:inline-block;width:10px;height:10px;border-radius:2px;"
            "margin-right:4px}\n"
            "figure{margin:10px 0 18px}figcaption{color:#555;font-size:13px;max-width:1320px}\n"
            ".panels{display:flex;flex-wrap:wrap;gap:10px;align-items:flex-start}.bars{margin:0;max-width:660px}\n"
            "svg{font:11px sans-serif;background:#fff}svg .title{font-size:13px;font-weight:600}\n"
            "svg .grid{stroke:#e2e2e2;fill:none}svg .minor{stroke:#f3f3f3;fill:none}"
            "svg .frame{fill:none;stroke:#444}\n"
            "svg .ty text,svg .cat{text-anchor:end}svg .tx,svg .tx text,svg .axis,svg .note{text-anchor:middle}"
            "svg .axis{font-size:12px}svg .note{fill:#999}svg .group{font-weight:600}\n"
            "svg .ref{stroke:#333;stroke-width:1.2;stroke-dasharray:5 4;fill:none}"
            "svg .series{fill:none;stroke-width:1.1;stroke-opacity:.85}"
            "svg .curve{fill:none;stroke-width:2}\n"
            "svg .box{stroke:#333;stroke-width:.8}svg .whisker{stroke:#333;fill:none}"
            "svg .median{stroke:#000;stroke-width:2}svg .dot{stroke:#0006;stroke-width:.5}\n"
      << "</style>\n</head>\n<body>\n";
  return out.str();
}

std::string pageEnd() {
  // No '<' or '&' in the script: the page stays checkable as plain markup (tests/test_report_html.cpp).
  return "<pre id=\"report-check\" hidden>pending</pre>\n<script>\n"
         "addEventListener('load', () => {\n"
         "  const charts = [...document.querySelectorAll('svg.chart')];\n"
         "  const within = (v, from, size) => Math.max(from - 1, Math.min(v, from + size + 1)) === v;\n"
         "  const inside = (mark, frame) => {\n"
         "    const b = mark.getBBox(), f = frame.getBBox();\n"
         "    return within(b.x + b.width / 2, f.x, f.width) ? within(b.y + b.height / 2, f.y, f.height) : false;\n"
         "  };\n"
         "  const empty = charts.filter(chart => {\n"
         "    const frame = chart.querySelector('.frame');\n"
         "    return !frame || ![...chart.querySelectorAll('.mark')].some(mark => inside(mark, frame));\n"
         "  });\n"
         "  const external = [...document.querySelectorAll('[src],link[href]')].map(e => e.src || e.href)\n"
         "      .concat(performance.getEntriesByType('resource').map(r => r.name));\n"
         "  const check = document.getElementById('report-check');\n"
         "  check.textContent = external.length ? 'external files: ' + external.join('; ')\n"
         "      : empty.length ? 'empty charts: ' + empty.map(chart => chart.getAttribute('aria-label')).join('; ')\n"
         "      : 'ok: ' + charts.length + ' charts with data';\n"
         "  check.dataset.pageHeight = document.documentElement.scrollHeight;\n"
         "});\n"
         "</script>\n</body>\n</html>\n";
}

}  // namespace stepcal::report::html
