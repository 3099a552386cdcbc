#!/usr/bin/env bash
# The lcm-spy image view (lcmtypes/java/vslam/spy) renders camera images
# headless: ImageViewRenderTest.java paints the plugin's panel for gray8,
# bgr8, jpeg and malformed vslam.image_t messages and checks pixels; the
# pictures are left in OUTDIR. Skips (77) when no JDK is found: the test runs
# as a Java source file, which needs java and its compiler.
#   test_image_view.sh JAVA TYPES_JAR LCM_JAR OUTDIR
set -euo pipefail
java=$1 types_jar=$2 lcm_jar=$3 out=$4
here="$(cd "$(dirname "$0")" && pwd)"
if [ -z "$java" ] || [ ! -x "$java" ] || ! "$java" --list-modules 2>/dev/null | grep -q '^jdk.compiler@'; then
  echo "SKIP: no JDK found (java '$java' missing or without jdk.compiler); install default-jdk-headless"
  exit 77
fi
for jar in "$types_jar" "$lcm_jar"; do
  [ -f "$jar" ] || { echo "FAIL: $jar not found (build the vslam_lcmtypes_java target)" >&2; exit 1; }
done
rm -rf "$out"
exec "$java" -Djava.awt.headless=true -cp "$types_jar:$lcm_jar" "$here/ImageViewRenderTest.java" "$out"
