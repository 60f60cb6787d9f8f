#!/usr/bin/env bash
# Opens an HTML report in headless Chromium and fails on any console message (the reports log
# nothing, so any is an error, e.g. an exception) or when the report's own check on load
# (tools/report/include/stepcal/report/html/page.hpp) finds a chart without data or a file the
# page refers to; saves a screenshot of the whole page. Every host name resolves to nothing: the
# check runs offline.
#   tests/system/check_report_in_browser.sh REPORT.html SCREENSHOT.png
# Exit 0: passed; 1: failed; 77 (ctest's SKIP_RETURN_CODE): no chromium, or REPORT.html.skip says
# why the report was not made.
set -euo pipefail

report=$1
screenshot=$2
readonly skip_code=77 max_height_px=24000 width_px=1400

browser=$(command -v chromium || command -v chromium-browser || true)
if [[ -z $browser ]]; then
  echo "SKIP: chromium is not installed (tools/setup.sh installs it)"
  exit $skip_code
fi
if [[ ! -f $report ]]; then
  if [[ -f $report.skip ]]; then
    echo "SKIP: $(cat "$report.skip")"
    exit $skip_code
  fi
  echo "FAIL: no report $report"
  exit 1
fi

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
url="file://$(realpath "$report")"
flags=(--headless --no-sandbox --disable-gpu --hide-scrollbars --no-first-run --disable-extensions
       --user-data-dir="$work/profile" --host-resolver-rules="MAP * ~NOTFOUND"
       --virtual-time-budget=10000)

# At the screenshot's width, so that the page height it reports is the one the screenshot needs.
timeout 120 "$browser" "${flags[@]}" --window-size="$width_px,1000" --enable-logging=stderr --v=0 --dump-dom "$url" \
  >"$work/dom.html" 2>"$work/log.txt"
failed=0
if grep -E ':CONSOLE[(:]' "$work/log.txt" >"$work/console.txt"; then
  echo "FAIL: console messages in $report:"
  sed 's/^/  /' "$work/console.txt"
  failed=1
fi
check=$(grep -o '<pre id="report-check"[^>]*>[^<]*</pre>' "$work/dom.html" || true)
result=$(sed -E 's/.*>([^<]*)<\/pre>/\1/' <<<"$check")
if [[ ! $result =~ ^ok:\ [1-9][0-9]*\ charts ]]; then
  echo "FAIL: report check of $report says: ${result:-nothing (its script did not run)}"
  failed=1
fi

height=$(sed -nE 's/.*data-page-height="([0-9]+)".*/\1/p' <<<"$check")
height=${height:-2000}
((height <= max_height_px)) || height=$max_height_px
mkdir -p "$(dirname "$screenshot")"
rm -f "$screenshot"
timeout 120 "$browser" "${flags[@]}" --screenshot="$(realpath -m "$screenshot")" \
  --window-size="$width_px,$height" "$url" >/dev/null 2>"$work/screenshot-log.txt"
if [[ ! -s $screenshot ]]; then
  echo "FAIL: no screenshot of $report"
  failed=1
fi
((failed)) && exit 1
echo "ok: $report ($result), screenshot $screenshot (${width_px}x$height px)"
