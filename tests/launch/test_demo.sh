#!/usr/bin/env bash
# scripts/demo end to end on the first 15 s of the apartment (CTest:
# launch.demo): the stack live as separate processes under scripts/launch in a
# private network namespace, the recording evaluated, and replayed; the demo
# itself exits 1 unless the back-end replayed over the live measurements gives
# the live numbers exactly.
#
#   tests/launch/test_demo.sh REPO_ROOT BUILD_DIR
set -euo pipefail
ROOT=$(cd "$1" && pwd)
BUILD=$(cd "$2" && pwd)
fail() { echo "FAIL: $*" >&2; exit 1; }

if [ "$(id -u)" -ne 0 ] || ! unshare --net true 2>/dev/null; then
  echo "SKIP: needs root and unshare --net for the demo's private LCM bus"
  exit 77
fi
work=$(mktemp -d "${TMPDIR:-/tmp}/vslam-test-demo.XXXXXX")
trap 'rm -rf "$work"' EXIT

status=0
DEMO_DIR=$work BUILD_DIR=$BUILD "$ROOT/scripts/demo" apartment --duration 15 --speed 1 \
  >"$work/demo.out" 2>&1 || status=$?
out=$work/apartment
if [ "$status" -ne 0 ]; then
  cat "$work/demo.out"
  tail -40 "$out/launch.log" 2>/dev/null || true
  fail "scripts/demo exited with $status"
fi

grep -q 'private network namespace' "$work/demo.out" || fail "the demo did not use its own bus"
# Every process ran: the simulator waited for them, drove 15 s and exited 0.
grep -q 'exited: sim (exit status 0' "$out/launch.log" || fail "vslam-sim did not exit 0"
grep -q 'simulated 15' "$out/launch.log" || fail "vslam-sim did not simulate 15 s"
for f in live/run.lcmlog accuracy.json accuracy_se2.json plots/trajectory.png plots/error.png \
  measurements.csv replay_backend.lcmlog replay.lcmlog; do
  [ -s "$out/$f" ] || fail "$f is missing or empty"
done
# The live front-ends measured landmarks that the back-end used.
measurements=$(($(wc -l <"$out/measurements.csv") - 1))
[ "$measurements" -ge 20 ] || fail "only $measurements visual measurements in the live run"
grep -q '"heading_deg"' "$out/accuracy.json" || fail "no heading error in accuracy.json"
grep -q 'the back-end replay reproduces the live run exactly' "$work/demo.out" ||
  fail "the back-end replay did not reproduce the live run"
echo "PASS: scripts/demo live + replay ($measurements measurements)"
