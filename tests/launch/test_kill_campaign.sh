#!/usr/bin/env bash
# scripts/kill-campaign's command line (CTest launch.kill_campaign_usage): the
# help, and the refusals of a bad command line (exit 2, naming what was wrong)
# before anything starts. The campaign itself runs the live stack for tens of
# minutes and is not part of the suite.
#
#   tests/launch/test_kill_campaign.sh REPO_ROOT
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

expect_usage_error() {  # WANTED-TEXT ARGS...: exit 2 and WANTED-TEXT on stderr
  local want=$1 status=0
  shift
  "$campaign" "$@" >"$work/out" 2>"$work/err" || status=$?
  [ "$status" -eq 2 ] || fail "'$*' exited $status, not 2: $(cat "$work/err")"
  grep -q -- "$want" "$work/err" || fail "'$*' did not say '$want': $(cat "$work/err")"
}
expect_usage_error "unknown kind 'camera'" --groups 'backend;camera' --out "$work/c"
expect_usage_error "--gap expects MIN,MAX" --gap 5 --out "$work/c"
expect_usage_error "--gap expects MIN,MAX" --gap 5,1 --out "$work/c"
expect_usage_error "--kills must be at least 1" --kills 0 --out "$work/c"
expect_usage_error "no scenario 'nowhere'" --scenario nowhere --out "$work/c"
expect_usage_error "bad command line" --no-such-option
# Nothing was started: no output directory.
[ ! -e "$work/c" ] || fail "a refused command line created its output directory"
echo "PASS: scripts/kill-campaign command line"
