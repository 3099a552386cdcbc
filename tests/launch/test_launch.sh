#!/usr/bin/env bash
# End-to-end test of scripts/launch (supervisord process groups), registered in
# CTest as launch.process_group. Needs no vslam binary: the group is
# tests/launch/test_group.conf, whose programs are tests/launch/test_prog.sh.
#
#   tests/launch/test_launch.sh [REPO_ROOT]
#
# Checks that scripts/launch
#   (a) starts every program and prefixes each line of its stdout and stderr
#       with "[name] ", and passes --lcm-url on; supervisorctl -c works;
#   (b) restarts a program with autorestart=true that exits 1, and leaves one
#       with autorestart=false down;
#   (e) after `kill -9` of the pid that supervisorctl shows for a program,
#       respawns it and leaves exactly one instance of it running (no orphan);
#   (c) on SIGTERM stops the programs with SIGINT one at a time in reverse
#       priority order, relays their shutdown output, exits in bounded time,
#       with status 3 naming the program that failed (once), and leaves no
#       process or run directory behind;
#   (d) refuses a profile naming a missing binary, names it, starts nothing;
#   (f) stops by itself and exits 3 when every program has failed (one
#       EXITED with an unexpected status, one FATAL), naming both;
#   (g) keeps the lines of programs that write partial lines whole and
#       newline-terminated, and exits 0 on SIGTERM when nothing failed;
# and that config/launch/*.conf are valid profiles (launch --check, with stub
# binaries).
# shellcheck disable=SC2015,SC2016 # `a && b || fail` and eval'd '...' are deliberate
set -euo pipefail

ROOT=$(cd "${1:-$(dirname "${BASH_SOURCE[0]}")/../..}" && pwd)
LAUNCH=$ROOT/scripts/launch
PROFILE=$ROOT/tests/launch/test_group.conf
URL='udpm://239.255.76.67:7999?ttl=0'

work=$(mktemp -d "${TMPDIR:-/tmp}/vslam-test-launch.XXXXXX")
out=$work/out
export TEST_LAUNCH_DIR=$work/state TEST_LAUNCH_PID=$$
mkdir -p "$TEST_LAUNCH_DIR"
launch_pid=""

# Kills, by pid, whatever this test started that is still alive.
cleanup() {
  if [ -n "$launch_pid" ] && kill -0 "$launch_pid" 2>/dev/null; then
    kill -TERM "$launch_pid" 2>/dev/null || true
    for _ in $(seq 150); do kill -0 "$launch_pid" 2>/dev/null || break; sleep 0.1; done
    kill -KILL "$launch_pid" 2>/dev/null || true
  fi
  local pid
  if [ -f "$out" ]; then
    for pid in $(sed -n "s/.*supervisord started with pid \([0-9]*\).*/\1/p" "$out"); do
      grep -qs supervisord "/proc/$pid/cmdline" && kill -KILL "$pid" 2>/dev/null || true
    done
  fi
  if [ -f "$TEST_LAUNCH_DIR/pids" ]; then
    while read -r pid; do
      grep -qs test_prog "/proc/$pid/cmdline" && kill -KILL "$pid" 2>/dev/null || true
    done <"$TEST_LAUNCH_DIR/pids"
  fi
  rm -rf "$work"
}
trap cleanup EXIT

fail() {
  echo "FAIL: $*" >&2
  if [ -f "$out" ]; then echo "--- scripts/launch output:" >&2; cat "$out" >&2; fi
  for f in starts stops; do
    [ -f "$TEST_LAUNCH_DIR/$f" ] && { echo "--- $f:" >&2; cat "$TEST_LAUNCH_DIR/$f" >&2; }
  done
  exit 1
}
pass() { echo "ok: $*"; }
# wait_for SECONDS DESCRIPTION CMD...: polls CMD every 0.1 s.
wait_for() {
  local secs=$1 what=$2
  shift 2
  local deadline=$((SECONDS + secs))
  until "$@"; do
    [ $SECONDS -lt $deadline ] || fail "timed out after ${secs}s waiting for $what"
    sleep 0.1
  done
}
has_line() { grep -qxF -- "$1" "$out"; }
count() { grep -cxF -- "$1" "$TEST_LAUNCH_DIR/starts" 2>/dev/null || true; }
alive() { kill -0 "$1" 2>/dev/null; }
# A process that exists and is not a zombie.
live() {
  local s
  s=$(sed -n 's/^State:[[:space:]]*\(.\).*/\1/p' "/proc/$1/status" 2>/dev/null)
  [ -n "$s" ] && [ "$s" != Z ]
}
# How many live processes test_prog.sh recorded for NAME MODE (pids file).
instances() {
  local pid n=0
  while read -r pid; do
    live "$pid" && tr '\0' ' ' <"/proc/$pid/cmdline" 2>/dev/null | grep -q "test_prog.sh $1 " && n=$((n + 1))
  done <"$TEST_LAUNCH_DIR/pids"
  echo "$n"
}

command -v supervisord >/dev/null || fail "supervisord is not installed (scripts/setup installs it)"

# --- (a) start, prefixed output ------------------------------------------------
"$LAUNCH" "$PROFILE" --lcm-url "$URL" >>"$out" 2>&1 &
launch_pid=$!

wait_for 20 "alpha and beta to print" \
  eval 'has_line "[alpha] hello from alpha" && has_line "[beta] hello from beta"'
has_line "[alpha] alpha on stderr" || fail "stderr of alpha is not prefixed with [alpha]"
has_line "[beta] beta on stderr" || fail "stderr of beta is not prefixed with [beta]"
has_line "[alpha] alpha args: --lcm-url $URL" || fail "--lcm-url $URL did not reach the programs"
if grep -v '^\[' "$out" | grep -q -e 'hello from' -e 'on stderr'; then
  fail "some program output is not prefixed"
fi
pass "(a) programs started, stdout and stderr prefixed with their names"

ctl=$(sed -n 's/^\[launch\] status: *\(supervisorctl -c [^ ]*\) status$/\1/p' "$out")
[ -n "$ctl" ] || fail "scripts/launch did not print the supervisorctl command"
run_dir=$(dirname "${ctl##* }")
# RUNNING once up for startsecs=1.
running() { $ctl status "$1" 2>/dev/null | grep -Eq "^$1 +RUNNING"; }
wait_for 15 "'$ctl status' to show alpha and beta RUNNING" eval 'running alpha && running beta'
pass "(a) '$ctl status' works"

# --- (b) restart policy ------------------------------------------------------
wait_for 20 "crasher (autorestart=true, exits 1) to be started 3 times" \
  eval '[ "$(count "crasher started")" -ge 3 ]'
wait_for 10 "once to exit" eval 'has_line "[once] once crashing"'
sleep 1.5  # time enough for a wrong restart of once to show
[ "$(count "once started")" -eq 1 ] || fail "once (autorestart=false) was started $(count "once started") times, expected 1"
[ "$(count "alpha started")" -eq 1 ] || fail "alpha was started $(count "alpha started") times, expected 1"
status=$($ctl status once 2>&1 || true)
grep -Eq '^once +EXITED' <<<"$status" || fail "once should be EXITED: $status"
pass "(b) crasher restarted ($(count "crasher started") starts), once left down"

# --- (e) kill -9 of the pid supervisorctl shows --------------------------------
old_pid=$($ctl pid alpha)
[ "$old_pid" -gt 0 ] 2>/dev/null || fail "'$ctl pid alpha' gave '$old_pid'"
[ "$(instances alpha)" -eq 1 ] || fail "$(instances alpha) instances of alpha before the kill, expected 1"
kill -KILL "$old_pid"
new_pid=""
respawned() { new_pid=$($ctl pid alpha 2>/dev/null) && [ "$new_pid" -gt 0 ] && [ "$new_pid" != "$old_pid" ] && running alpha; }
wait_for 15 "alpha to be respawned after kill -9 of pid $old_pid" respawned
wait_for 5 "one alpha left after the respawn (the killed one's program must die with it)" \
  eval '[ "$(instances alpha)" -eq 1 ]'
[ "$(count "alpha started")" -eq 2 ] || fail "alpha was started $(count "alpha started") times, expected 2"
pass "(e) kill -9 of alpha's pid $old_pid: respawned as $new_pid, one alpha running"

# --- (c) ordered stop on SIGTERM ---------------------------------------------
alive "$launch_pid" || fail "scripts/launch exited early"
t0=$SECONDS
kill -TERM "$launch_pid"
wait_for 30 "scripts/launch to exit after SIGTERM" eval '! alive "$launch_pid"'
rc=0
wait "$launch_pid" || rc=$?
launch_pid=""
[ "$rc" -eq 3 ] || fail "scripts/launch exited with status $rc after SIGTERM while once had failed, expected 3"
grep -q '^\[launch\] failed: once (EXITED' "$out" || fail "the failed program once is not named"
! grep -Eq '^\[launch\] failed: (alpha|beta|crasher) ' "$out" || fail "a program that had not failed is named as failed"
expected=$'beta stopping\nbeta stopped\nalpha stopping\nalpha stopped'
actual=$(cat "$TEST_LAUNCH_DIR/stops" 2>/dev/null || true)
[ "$actual" = "$expected" ] ||
  fail "stop order (beta has priority 200, alpha 100; beta takes 1 s): got"$'\n'"$actual"
has_line "[beta] beta bye" && has_line "[alpha] alpha bye" ||
  fail "output printed while stopping was lost or not prefixed"
while read -r pid; do
  ! live "$pid" || fail "program pid $pid still running after scripts/launch exited"
done <"$TEST_LAUNCH_DIR/pids"
[ ! -e "$run_dir" ] || fail "run directory $run_dir left behind"
pass "(c) SIGTERM: beta then alpha stopped with SIGINT, exit 3 (once failed) after $((SECONDS - t0))s"

# --- (d) missing binary --------------------------------------------------------
: >"$TEST_LAUNCH_DIR/starts"
cat >"$work/missing.conf" <<'CONF'
[program:present]
command=%(ENV_VSLAM_ROOT)s/scripts/lib/prefix-output %(program_name)s
  %(ENV_VSLAM_ROOT)s/tests/launch/test_prog.sh %(program_name)s serve
priority=1
stopsignal=INT

[program:absent]
command=%(ENV_VSLAM_ROOT)s/scripts/lib/prefix-output %(program_name)s
  %(ENV_VSLAM_BIN)s/vslam-does-not-exist --instance %(program_name)s
priority=2
CONF
rc=0
VSLAM_BIN=$work/bin timeout 60 "$LAUNCH" "$work/missing.conf" >"$work/missing.out" 2>&1 || rc=$?
msg=$(cat "$work/missing.out")
[ "$rc" -ne 0 ] && [ "$rc" -ne 124 ] || fail "missing binary: scripts/launch exited with $rc; output: $msg"
grep -q "$work/bin/vslam-does-not-exist" <<<"$msg" || fail "missing binary not named: $msg"
grep -q "missing.conf" <<<"$msg" || fail "profile not named: $msg"
grep -q "'absent'" <<<"$msg" || fail "program not named: $msg"
[ ! -s "$TEST_LAUNCH_DIR/starts" ] || fail "a program was started despite the missing binary"
pass "(d) missing binary refused (exit $rc): $(head -1 <<<"$msg")"

rc=0
"$LAUNCH" no-such-profile >"$work/none.out" 2>&1 || rc=$?
[ "$rc" -ne 0 ] && grep -q no-such-profile "$work/none.out" || fail "unknown profile: exit $rc, $(cat "$work/none.out")"
pass "unknown profile refused"

# --- --programs: one computer's share of the profile --------------------------
rc=0
"$LAUNCH" "$PROFILE" --programs beta,alpha --check >"$work/programs.out" 2>&1 || rc=$?
[ "$rc" -eq 0 ] || fail "--programs beta,alpha --check: exit $rc: $(cat "$work/programs.out")"
order=$(sed -n 's/.*start order.*: //p' "$work/programs.out")
[[ $order == "alpha("*") beta("*")" ]] || fail "--programs beta,alpha ran other programs: $order"
rc=0
"$LAUNCH" "$PROFILE" --programs alpha,gamma --check >"$work/programs.out" 2>&1 || rc=$?
[ "$rc" -eq 2 ] && grep -q "no program 'gamma'" "$work/programs.out" &&
  grep -q "alpha beta crasher once" "$work/programs.out" ||
  fail "--programs naming an unknown program: exit $rc: $(cat "$work/programs.out")"
pass "--programs runs only the programs named, refuses one the profile lacks"

# --- (f) a group whose programs all fail stops by itself, non-zero ------------
cat >"$work/failing.conf" <<'CONF'
; Exits 3 at once and is not restarted: EXITED, status not in exitcodes.
[program:quits]
command=%(ENV_VSLAM_ROOT)s/scripts/lib/prefix-output %(program_name)s sh -c 'echo quitting; exit 3'
autorestart=false
startsecs=0
redirect_stderr=true
stdout_logfile=/dev/stdout
stdout_logfile_maxbytes=0

; Exits 1 before startsecs, with no retry left: FATAL.
[program:never_up]
command=%(ENV_VSLAM_ROOT)s/scripts/lib/prefix-output %(program_name)s false
startsecs=5
startretries=0
redirect_stderr=true
stdout_logfile=/dev/stdout
stdout_logfile_maxbytes=0
CONF
rc=0
timeout 30 "$LAUNCH" "$work/failing.conf" --lcm-url "$URL" >"$work/failing.out" 2>&1 || rc=$?
msg=$(cat "$work/failing.out")
[ "$rc" -eq 3 ] || fail "all programs failed: scripts/launch exited with $rc (124: did not stop by itself), expected 3: $msg"
grep -q '^\[launch\] failed: quits (EXITED' <<<"$msg" || fail "quits not named as failed: $msg"
grep -q '^\[launch\] failed: never_up (FATAL' <<<"$msg" || fail "never_up not named as failed: $msg"
pass "(f) every program failed: stopped by itself, exit 3"

# --- (g) partial lines stay whole; a clean stop exits 0 ------------------------
# p1 and p2 each hold a partial line for 0.3 s while the other writes, and end
# with a line that has no newline; calm runs until stopped.
: >"$TEST_LAUNCH_DIR/starts"
: >"$TEST_LAUNCH_DIR/pids"
: >"$TEST_LAUNCH_DIR/stops"
{
  for p in "p1 partial 0" "p2 partial 0.15" "calm serve 0"; do
    read -r prog mode delay <<<"$p"
    cat <<CONF
[program:$prog]
command=%(ENV_VSLAM_ROOT)s/scripts/lib/prefix-output %(program_name)s
  %(ENV_VSLAM_ROOT)s/tests/launch/test_prog.sh %(program_name)s $mode $delay
autorestart=unexpected
startsecs=0
stopsignal=INT
stopasgroup=true
killasgroup=true
redirect_stderr=true
stdout_logfile=/dev/stdout
stdout_logfile_maxbytes=0

CONF
  done
} >"$work/partial.conf"
out=$work/partial.out
"$LAUNCH" "$work/partial.conf" --lcm-url "$URL" >"$out" 2>&1 &
launch_pid=$!
wait_for 20 "p1 and p2 to exit" eval 'grep -q "exited: p1 " "$out" && grep -q "exited: p2 " "$out"'
sleep 0.5  # what else would be written after them
kill -TERM "$launch_pid"
wait_for 30 "scripts/launch to exit after SIGTERM" eval '! alive "$launch_pid"'
rc=0
wait "$launch_pid" || rc=$?
launch_pid=""
for p in p1 p2; do
  for line in "[$p] $p part one" "[$p] $p unterminated"; do
    has_line "$line" || fail "no line '$line' on its own: $(grep -F "$p " "$out" || true)"
  done
done
[ "$rc" -eq 0 ] || fail "clean stop (nothing failed): scripts/launch exited with $rc, expected 0"
grep -q 'calm stopped' "$TEST_LAUNCH_DIR/stops" || fail "calm was not stopped with SIGINT"
pass "(g) partial lines of p1 and p2 whole and newline-terminated; clean stop: exit 0"

# --- the shipped profiles parse and name only known binaries -------------------
mkdir -p "$work/bin"
for exe in $(grep -oh 'ENV_VSLAM_BIN)s/vslam-[a-z0-9_-]*' "$ROOT"/config/launch/*.conf | sed 's|.*/||' | sort -u); do
  printf '#!/bin/sh\nexit 0\n' >"$work/bin/$exe"
  chmod +x "$work/bin/$exe"
done
: >"$work/vslam.yaml"
for conf in "$ROOT"/config/launch/*.conf; do
  name=$(basename "$conf" .conf)
  rc=0
  VSLAM_BIN=$work/bin VSLAM_LOG_DIR=$work/logs VSLAM_REPLAY_LOG=$work/replay.lcmlog \
    "$LAUNCH" "$name" --check --config "$work/vslam.yaml" >"$work/check.out" 2>&1 || rc=$?
  [ "$rc" -eq 0 ] || fail "launch $name --check: exit $rc: $(cat "$work/check.out")"
  grep -q 'start order.*logger(' "$work/check.out" || fail "profile $name has no logger: $(cat "$work/check.out")"
  pass "profile $name: $(grep 'start order' "$work/check.out" | sed 's/.*: //')"
done

echo "PASS: launch.process_group"
