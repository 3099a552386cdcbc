#!/usr/bin/env bash
# vslam-viewer end to end (viewer.cli): over a replayed 10 s of the apartment,
# headless snapshots every 5 s of robot time (and the last frame); no display
# and no --snapshot is refused naming the way out; a bad --size is refused;
# under Xvfb (where installed) the window opens and the viewer ends on SIGTERM.
set -euo pipefail
root=$1
bin=$2/bin
out=$(mktemp -d /tmp/vslam-test-viewer.XXXXXX)
trap 'rm -rf "$out"; [ -n "${xvfb:-}" ] && kill "$xvfb" 2>/dev/null || true' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
cfg=$root/config/vslam.yaml

"$bin/vslam-sim" --config "$cfg" --scenario apartment --duration 10 --out "$out/sim.lcmlog" \
  >"$out/sim.txt" 2>&1 || { cat "$out/sim.txt" >&2; fail "vslam-sim"; }
"$bin/vslam-replay" "$out/sim.lcmlog" --config "$cfg" --out "$out/run.lcmlog" \
  >"$out/replay.txt" 2>&1 || { tail "$out/replay.txt" >&2; fail "vslam-replay"; }

env -u DISPLAY "$bin/vslam-viewer" --config "$cfg" --log "$out/run.lcmlog" --speed 0 \
  --snapshot "$out/snap" --every 5 >"$out/viewer.txt" 2>&1 || { cat "$out/viewer.txt" >&2; fail "snapshots"; }
n=$(ls "$out/snap" | wc -l)
[ "$n" -eq 3 ] || { ls "$out/snap" >&2; fail "$n snapshots, expected 3 (0, 5 and 10 s)"; }
/usr/bin/python3 - "$out/snap" <<'PY' || fail "a snapshot is not a 1280x720 image with content"
import os, sys
import matplotlib.image as mpimg
d = sys.argv[1]
files = sorted(os.listdir(d))
for f in files:
    img = mpimg.imread(os.path.join(d, f))
    assert img.shape[:2] == (720, 1280), (f, img.shape)
# The last one: trajectories and the camera images, not a blank frame.
assert mpimg.imread(os.path.join(d, files[-1])).std() > 0.05, files[-1]
PY

rc=0
env -u DISPLAY "$bin/vslam-viewer" --config "$cfg" --log "$out/run.lcmlog" >"$out/nodisplay.txt" 2>&1 || rc=$?
[ "$rc" -eq 2 ] || fail "without a display or --snapshot: exit $rc, expected 2"
grep -q "give --snapshot DIR" "$out/nodisplay.txt" || { cat "$out/nodisplay.txt" >&2; fail "no hint"; }
rc=0
"$bin/vslam-viewer" --log "$out/run.lcmlog" --snapshot "$out/x" --size 12x9 >"$out/size.txt" 2>&1 || rc=$?
[ "$rc" -eq 2 ] && grep -q -- "--size" "$out/size.txt" || { cat "$out/size.txt" >&2; fail "bad --size"; }

if command -v Xvfb >/dev/null; then
  Xvfb -displayfd 3 -screen 0 1400x800x24 -nolisten tcp 3>"$out/display" 2>"$out/xvfb.txt" &
  xvfb=$!
  for _ in $(seq 100); do [ -s "$out/display" ] && break; sleep 0.1; done
  [ -s "$out/display" ] || fail "Xvfb did not start"
  DISPLAY=:$(cat "$out/display") "$bin/vslam-viewer" --config "$cfg" --log "$out/run.lcmlog" \
    --speed 0 >"$out/window.txt" 2>&1 &
  viewer=$!
  for _ in $(seq 300); do grep -q "end of" "$out/window.txt" && break; sleep 0.1; done
  grep -q "window on display" "$out/window.txt" || { cat "$out/window.txt" >&2; fail "no window"; }
  grep -q "end of" "$out/window.txt" || { cat "$out/window.txt" >&2; fail "the window did not play the log"; }
  kill -TERM "$viewer"
  rc=0
  wait "$viewer" || rc=$?
  [ "$rc" -eq 0 ] || { cat "$out/window.txt" >&2; fail "the window ended with $rc on SIGTERM"; }
else
  echo "note: no Xvfb: the window is not tested"
fi
echo "PASS: vslam-viewer"
