#!/usr/bin/env bash
# lcm-spy must decode every vslam type: write a log with all of them, run
# `scripts/spy --check` on it, and require one decoded row per .lcm file.
# Also checks that a message lcm-spy does not know is reported as a failure.
set -euo pipefail
writer=$1 root=$2 build=$3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$writer" "$tmp/all.lcmlog"
BUILD_DIR="$build" "$root/scripts/spy" --check "$tmp/all.lcmlog" | tee "$tmp/table.txt"
expected=$(ls "$root"/lcmtypes/*.lcm | wc -l)
decoded=$(grep -cE '^SPY_\S+\s+vslam\.\S+\s+3\s+0' "$tmp/table.txt" || true)
if [ "$decoded" -ne "$expected" ]; then
  echo "FAIL: $decoded of $expected types decoded by lcm-spy's type database" >&2
  exit 1
fi
# Negative control: an unknown fingerprint must make the check fail.
python3 - "$tmp/all.lcmlog" "$tmp/bad.lcmlog" <<'PY'
import struct, sys
data = open(sys.argv[1], 'rb').read()
# First event: header is sync(4) eventnum(8) timestamp(8) chanlen(4) datalen(4), channel, data.
chanlen, datalen = struct.unpack('>ii', data[20:28])
start = 28 + chanlen
bad = bytearray(data[:start + datalen])
bad[start:start + 8] = b'\x01\x02\x03\x04\x05\x06\x07\x08'   # fingerprint nobody has
open(sys.argv[2], 'wb').write(bad)
PY
if BUILD_DIR="$build" "$root/scripts/spy" --check "$tmp/bad.lcmlog" > "$tmp/bad.txt" 2>&1; then
  echo "FAIL: an unknown type was not reported" >&2
  cat "$tmp/bad.txt" >&2
  exit 1
fi
grep -q "no type with fingerprint 0102030405060708" "$tmp/bad.txt"
echo "PASS: lcm-spy decodes all $expected vslam types and reports unknown ones"
