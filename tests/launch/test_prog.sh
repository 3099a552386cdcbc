#!/usr/bin/env bash
# A stand-in process for tests/launch/test_launch.sh (no vslam binary needed).
#
#   test_prog.sh NAME MODE [STOP_DELAY] [ARGS...]
#
# Appends "NAME started" to $TEST_LAUNCH_DIR/starts and its pid to
# $TEST_LAUNCH_DIR/pids, prints "hello from NAME" on stdout, "NAME on stderr"
# on stderr and "NAME args: ARGS" on stdout, then by MODE:
#   serve  runs until SIGINT (SIGTERM kills it without a trace, so a wrong
#          stopsignal shows); on SIGINT appends "NAME stopping" to
#          $TEST_LAUNCH_DIR/stops, sleeps STOP_DELAY seconds, appends
#          "NAME stopped", prints "NAME bye" and exits 0
#   crash  exits with status 1 after 0.3 s (exits 0 on SIGINT)
#   partial  waits STOP_DELAY seconds, prints "NAME part" without a newline,
#          0.3 s later ends that line with " one", then prints
#          "NAME unterminated" with no newline at all and exits 0
set -euo pipefail
name=$1 mode=$2 delay=${3:-0}
shift 2; [ $# -gt 0 ] && shift
dir=${TEST_LAUNCH_DIR:?TEST_LAUNCH_DIR must be set}
echo "$name started" >>"$dir/starts"
echo "$$" >>"$dir/pids"
echo "hello from $name"
echo "$name on stderr" >&2
echo "$name args: $*"

case $mode in
  serve)
    on_int() {
      echo "$name stopping" >>"$dir/stops"
      sleep "$delay"
      echo "$name stopped" >>"$dir/stops"
      echo "$name bye"
      exit 0
    }
    trap on_int INT
    trap - TERM
    # Orphan guard: give up if the test that started us is gone.
    while [ -z "${TEST_LAUNCH_PID:-}" ] || kill -0 "$TEST_LAUNCH_PID" 2>/dev/null; do
      sleep 0.1
    done
    ;;
  crash)
    trap 'exit 0' INT
    sleep 0.3
    echo "$name crashing"
    exit 1
    ;;
  partial)
    sleep "$delay"
    printf '%s part' "$name"
    sleep 0.3
    printf ' one\n%s unterminated' "$name"
    exit 0
    ;;
  *) echo "test_prog.sh: unknown mode $mode" >&2; exit 2 ;;
esac
