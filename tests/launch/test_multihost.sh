#!/usr/bin/env bash
# scripts/multihost --check on the first 20 s of the apartment (CTest:
# launch.multihost): the stack split over three network namespaces on a
# bridge (robot: simulator; compute: front-ends and appearance; server:
# landmark DB, back-end, dead reckoning), LCM with ttl=1. Passes when the
# server's recorder heard every program, vSLAM is within 0.3 m (ATE mean),
# each computer ran only its share, and a ttl=0 publisher on the robot is not
# heard by the server while a ttl=1 one is. Skips without root / ip netns.
#
#   tests/launch/test_multihost.sh REPO_ROOT BUILD_DIR
set -euo pipefail
ROOT=$(cd "$1" && pwd)
BUILD=$(cd "$2" && pwd)
fail() { echo "FAIL: $*" >&2; exit 1; }

work=$(mktemp -d "${TMPDIR:-/tmp}/vslam-test-multihost.XXXXXX")
trap 'rm -rf "$work"' EXIT

status=0
BUILD_DIR=$BUILD "$ROOT/scripts/multihost" --duration 20 --layouts three-hosts --check \
  --out "$work" >"$work/multihost.out" 2>&1 || status=$?
if [ "$status" -eq 77 ]; then
  echo "SKIP: $(tail -1 "$work/multihost.out")"
  exit 77
fi
cat "$work/multihost.out"
[ "$status" -eq 0 ] || fail "scripts/multihost --check exited with $status"
# Each computer's scripts/launch started its share and nothing else.
started() { sed -n 's/.*start order.*: //p' "$work/three-hosts/launch-$1.log"; }
[[ $(started robot) == "sim(900)" ]] || fail "robot ran: $(started robot)"
[[ $(started compute) == "appearance(300) frontend_forward(500) frontend_backward(510)" ]] ||
  fail "compute ran: $(started compute)"
[[ $(started server) == "landmark_db(100) backend(200) deadreckon(400)" ]] ||
  fail "server ran: $(started server)"
grep -q '| three-hosts |.*| ttl=1 |' "$work/report.md" || fail "no three-host row in the report"
echo "PASS: launch.multihost"
