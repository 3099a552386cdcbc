#!/usr/bin/env bash
# scripts/bench (CTest launch.bench_script): one quick figure measured for
# real (one visual measurement, one repetition), its table row against the
# target and its JSON; a second run compared with the first; bad options
# refused with exit 2. The full set takes minutes and is not in the suite.
#
#   tests/launch/test_bench_script.sh REPO_ROOT BUILD_DIR
set -euo pipefail
ROOT=$(cd "$1" && pwd)
export BUILD_DIR=$2
fail() { echo "FAIL: $*" >&2; exit 1; }
bench=$ROOT/scripts/bench
if [ ! -x "$BUILD_DIR/bin/bench_measurement" ]; then
  echo "SKIP: $BUILD_DIR/bin/bench_measurement not built (VSLAM_BUILD_BENCHMARKS=OFF)"
  exit 77
fi
work=$(mktemp -d "${TMPDIR:-/tmp}/vslam-test-bench.XXXXXX")
trap 'rm -rf "$work"' EXIT

"$bench" --only measurement_50 --repetitions 2 --min-time 0.01 --json "$work/a.json" >"$work/a.out" 2>&1 ||
  fail "scripts/bench exited $?: $(cat "$work/a.out")"
grep -q "| one visual measurement, 50 pairs with 20% outliers (ms) | [0-9.]* | <= 2 | \(yes\|no\) |" \
  "$work/a.out" || fail "no table row for measurement_50: $(cat "$work/a.out")"
/usr/bin/python3 - "$work/a.json" <<'PY' || fail "bad JSON: $(cat "$work/a.json")"
import json, sys
d = json.load(open(sys.argv[1]))
v = d["figures"]["measurement_50"]
assert 0.01 < v < 1000, v  # ms: a real measurement, not a placeholder
assert d["targets"]["measurement_50"]["target"] == 2.0
assert d["machine"]["cores"] >= 1 and d["commit"] and d["repetitions"] == 2
PY

"$bench" --only measurement_50 --repetitions 1 --min-time 0.01 --json "$work/b.json" \
  --compare "$work/a.json" >"$work/b.out" 2>&1 || fail "--compare exited $?: $(cat "$work/b.out")"
grep -q "| before | after / before |" "$work/b.out" || fail "--compare: no before column: $(cat "$work/b.out")"

# shellcheck source=usage_error.sh
. "$(dirname "$0")/usage_error.sh"
script=$bench
expect_usage_error "unknown figure(s) sift" --only sift
expect_usage_error "no such log" --replay "$work/none.lcmlog"
expect_usage_error "not a scripts/bench JSON file" --compare "$work/a.out"
expect_usage_error "bad command line" --repetitions
echo "PASS: scripts/bench measures, tabulates, writes JSON, compares and refuses bad options"
