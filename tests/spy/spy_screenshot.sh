#!/usr/bin/env bash
# The real lcm-spy draws camera images: under Xvfb, in a private network
# namespace, it watches a short simulated log played in a loop, and
# SpyScreenshot.java double-clicks CAM_FORWARD_IMAGE in its table (lcm-spy
# then opens the image view plugin from the types jar), waits for a decoded
# frame in the view and saves a screenshot. Makes docs/img/lcm-spy-image.png;
# as the CTest spy.image_view_lcm_spy it writes into the build tree. Skips (77)
# without root and unshare --net, Xvfb, a JDK or vslam-sim.
#   tests/spy/spy_screenshot.sh [OUT.png]
# BUILD_DIR (default build/) has the types jar and, unless VSLAM_SIM names
# another, bin/vslam-sim.
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
build="${BUILD_DIR:-$root/build}"
sim="${VSLAM_SIM:-$build/bin/vslam-sim}"
out="$(realpath -m "${1:-$root/docs/img/lcm-spy-image.png}")"
jar="$build/share/java/vslam_lcmtypes_java.jar"
if [ "$(id -u)" -ne 0 ] || ! unshare --net true 2>/dev/null; then
  echo "SKIP: needs root and unshare --net for a private LCM bus"; exit 77
fi
command -v Xvfb > /dev/null || { echo "SKIP: no Xvfb (Debian xvfb)"; exit 77; }
command -v javac > /dev/null || { echo "SKIP: no JDK (javac) found"; exit 77; }
[ -x "$sim" ] || { echo "SKIP: $sim not built"; exit 77; }
[ -f "$jar" ] || { echo "FAIL: $jar not found (build vslam_lcmtypes_java)" >&2; exit 1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
(cd "$root" && "$sim" --scenario apartment --duration 3 --out "$tmp/cams.lcmlog") > "$tmp/sim.txt" 2>&1 ||
  { cat "$tmp/sim.txt" >&2; exit 1; }
export VSLAM_ROOT="$root" VSLAM_JAR="$jar" VSLAM_TMP="$tmp" VSLAM_OUT="$out"
unshare --net bash -c '
set -euo pipefail -m  # -m: each background job in its own process group, killed whole
ip link set lo up; ip link set lo multicast on; ip route add 224.0.0.0/4 dev lo
url="udpm://239.255.76.67:7667?ttl=0"
# -displayfd: Xvfb picks a free display (tests run in parallel) and writes it.
Xvfb -displayfd 3 -screen 0 1060x400x24 -nolisten tcp 3> "$VSLAM_TMP/display" 2> "$VSLAM_TMP/xvfb.txt" &
xvfb=$!
(while true; do lcm-logplayer --lcm-url="$url" "$VSLAM_TMP/cams.lcmlog"; done) > /dev/null 2>&1 &
player=$!
trap "kill -- -$player -$xvfb 2>/dev/null || true" EXIT
for _ in $(seq 100); do [ -s "$VSLAM_TMP/display" ] && break; sleep 0.1; done
[ -s "$VSLAM_TMP/display" ] || { echo "FAIL: Xvfb did not start:" >&2; cat "$VSLAM_TMP/xvfb.txt" >&2; exit 1; }
DISPLAY=":$(head -n1 "$VSLAM_TMP/display")" java \
  -cp "$VSLAM_JAR:/usr/share/java/lcm.jar:/usr/share/java/jchart2d.jar" \
  "$VSLAM_ROOT/tests/spy/SpyScreenshot.java" "$url" CAM_FORWARD_IMAGE "$VSLAM_OUT"
'
echo "PASS: lcm-spy opened the image view on CAM_FORWARD_IMAGE and drew a frame; $out"
