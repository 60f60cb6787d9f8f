#!/usr/bin/env bash
# Shows that tests/system/check_report_in_browser.sh can fail: a good report, broken three ways (a chart
# without data, a script error, an image from the network), must fail each time.
#   tests/system/check_report_in_browser_selftest.sh GOOD_REPORT.html WORK_DIR
# Exit 0: every broken copy failed; 1: one passed; 77: the checker skipped (no chromium).
set -euo pipefail

good=$1
work=$2
checker=$(dirname "$0")/check_report_in_browser.sh
mkdir -p "$work"

declare -A injected=(
  [empty-chart]='<svg class="chart" aria-label="injected chart without data" width="100" height="100"><rect class="frame" x="10" y="10" width="80" height="80"/></svg>'
  [script-error]='<script>reportThatDoesNotExist.render();</script>'
  [network-image]='<img alt="" src="http://example.com/plot.png">'
)
status=0
for name in "${!injected[@]}"; do
  broken=$work/broken-$name.html
  # Before the page's own check script, so that it sees the injected chart too.
  awk -v add="${injected[$name]}" '/<pre id="report-check"/ && !done { print add; done = 1 } { print }' \
    "$good" >"$broken"
  set +e
  "$checker" "$broken" "$work/broken-$name.png" >"$work/broken-$name.log" 2>&1
  code=$?
  set -e
  case $code in
    1) echo "ok: broken ($name) fails: $(grep -m1 FAIL "$work/broken-$name.log")" ;;
    77) cat "$work/broken-$name.log"; exit 77 ;;
    *) echo "FAIL: broken ($name) gave exit $code:"; cat "$work/broken-$name.log"; status=1 ;;
  esac
done
exit $status
