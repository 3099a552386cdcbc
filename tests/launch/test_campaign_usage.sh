#!/usr/bin/env bash
# The command lines of scripts/kill-campaign, scripts/soak and
# scripts/multihost (CTest launch.campaign_usage): the help, and the
# refusals of a bad command line (exit 2, naming what was wrong) before
# anything starts. The campaigns themselves run the live stack for tens of
# minutes and are not part of the suite (a short multihost run is:
# launch.multihost).
#
#   tests/launch/test_campaign_usage.sh REPO_ROOT
set -euo pipefail
ROOT=$(cd "$1" && pwd)
fail() { echo "FAIL: $*" >&2; exit 1; }
campaign=$ROOT/scripts/kill-campaign
work=$(mktemp -d "${TMPDIR:-/tmp}/vslam-test-kill-campaign.XXXXXX")
trap 'rm -rf "$work"' EXIT

out=$("$campaign" --help) || fail "--help exited $?"
for option in --scenario --kills --seed --speed --groups --gap --out --report --analyse; do
  grep -q -- "$option" <<<"$out" || fail "--help does not mention $option"
done

# shellcheck source=usage_error.sh
. "$(dirname "$0")/usage_error.sh"
script=$campaign
expect_usage_error "unknown kind 'camera'" --groups 'backend;camera' --out "$work/c"
expect_usage_error "--gap expects MIN,MAX" --gap 5 --out "$work/c"
expect_usage_error "--gap expects MIN,MAX" --gap 5,1 --out "$work/c"
expect_usage_error "--kills must be at least 1" --kills 0 --out "$work/c"
expect_usage_error "no scenario 'nowhere'" --scenario nowhere --out "$work/c"
expect_usage_error "bad command line" --no-such-option
# Nothing was started: no output directory.
[ ! -e "$work/c" ] || fail "a refused command line created its output directory"
echo "ok: scripts/kill-campaign command line"

script=$ROOT/scripts/soak
out=$("$script" --help) || fail "soak --help exited $?"
for option in lockstep live --hours --minutes --speed --scenario --out --keep-logs; do
  grep -q -- "$option" <<<"$out" || fail "soak --help does not mention $option"
done
expect_usage_error "bad command line" sideways --out "$work/c"
expect_usage_error "must be > 0" --hours 0 --out "$work/c"
expect_usage_error "must be > 0" live --speed -1 --out "$work/c"
expect_usage_error "no scenario 'nowhere'" --scenario nowhere --out "$work/c"
[ ! -e "$work/c" ] || fail "a refused soak command line created its output directory"
echo "ok: scripts/soak command line"

script=$ROOT/scripts/multihost
out=$("$script" --help) || fail "multihost --help exited $?"
for option in --scenario --duration --speed --layouts --link-loss --out --check --max-ate; do
  grep -q -- "$option" <<<"$out" || fail "multihost --help does not mention $option"
done
expect_usage_error "unknown layout 'two-hosts'" --layouts three-hosts,two-hosts --out "$work/c"
expect_usage_error "must be > 0" --speed 0 --out "$work/c"
expect_usage_error "--link-loss expects percentages" --link-loss 1,lots --out "$work/c"
expect_usage_error "each percentage must be in (0, 100)" --link-loss 0.5,100 --out "$work/c"
expect_usage_error "no scenario 'nowhere'" --scenario nowhere --out "$work/c"
expect_usage_error "bad command line" --no-such-option
[ ! -e "$work/c" ] || fail "a refused multihost command line created its output directory"
echo "PASS: scripts/kill-campaign, scripts/soak and scripts/multihost command lines"
