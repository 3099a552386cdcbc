#!/usr/bin/env bash
# scripts/experiment-cameras on 10 s of the apartment (launch.experiment_cameras):
# four camera set-ups replayed over one simulated run (and its alternating
# twin), one table row each, the plot written, and a bad scenario refused.
set -euo pipefail
root=$1
build=$2
out=$(mktemp -d /tmp/vslam-test-expcam.XXXXXX)
trap 'rm -rf "$out"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

BUILD_DIR=$build "$root/scripts/experiment-cameras" apartment --duration 10 --out "$out/run" \
  >"$out/log" 2>&1 || { tail -20 "$out/log" >&2; fail "experiment-cameras exited non-zero"; }
for setup in "forward only" "backward only" "forward + backward |" "forward + backward, taking turns"; do
  grep -q "^| $setup" "$out/run/table.md" || { cat "$out/run/table.md" >&2; fail "no row '$setup'"; }
done
rows=$(grep -c '^| [fb]' "$out/run/table.md")
[ "$rows" -eq 4 ] || fail "$rows rows in table.md, expected 4"
# Every row has an error in metres and CPU seconds > 0.
awk -F'|' '/^\| [fb]/ { split($4, ate, "/"); if (ate[1] + 0 <= 0 || $7 + 0 <= 0) bad = 1 }
           END { exit bad }' "$out/run/table.md" || { cat "$out/run/table.md" >&2; fail "a row without ATE or CPU"; }
[ -s "$out/run/cameras.png" ] || fail "no cameras.png"
[ ! -e "$out/run/sim.lcmlog" ] || fail "the simulated log was not removed"

if "$root/scripts/experiment-cameras" no_such_home --out "$out/bad" >"$out/bad.log" 2>&1; then
  fail "an unknown scenario was accepted"
fi
grep -q "no scenario 'no_such_home'" "$out/bad.log" || { cat "$out/bad.log" >&2; fail "no message naming the scenario"; }
echo "PASS: experiment-cameras"
