#!/usr/bin/env bash
# lcm-spy must decode every vslam type: write a log with all of them, run
# `scripts/spy --check` on it, and require one decoded row per .lcm file.
# LCM's own self-test events (which lcm-logger records) are listed apart and
# pass. Damaged copies of the log must each fail with a message naming the
# problem and where it is: an unknown fingerprint, a file cut inside a payload
# and inside a header, a garbled stretch over a sync word, a payload that does
# not decode, a payload with bytes left over, and issue 19's landmark request
# claiming 500,000,000 ids (which must fail fast, not take gigabytes).
set -euo pipefail
writer=$1 root=$2 build=$3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
spy_check() { BUILD_DIR="$build" "$root/scripts/spy" --check "$@"; }

"$writer" "$tmp/all.lcmlog"
spy_check "$tmp/all.lcmlog" | tee "$tmp/table.txt"
expected=$(ls "$root"/lcmtypes/*.lcm | wc -l)
decoded=$(grep -cE '^SPY_\S+\s+vslam\.\S+\s+3\s+0' "$tmp/table.txt" || true)
if [ "$decoded" -ne "$expected" ]; then
  echo "FAIL: $decoded of $expected types decoded by lcm-spy's type database" >&2
  exit 1
fi
grep -q "^log OK: $((expected * 3)) events" "$tmp/table.txt"

# Copies of the log, each with one kind of damage (or the self-test events),
# and for each the text the check must print. Offsets come from the log.
/usr/bin/python3 - "$tmp" <<'PY'
import struct, sys
tmp = sys.argv[1]
data = open(tmp + '/all.lcmlog', 'rb').read()
SYNC = 0xEDA1DA01

# Event header: sync(4) eventnum(8) timestamp(8) chanlen(4) datalen(4), channel, data.
def event(eventnum, channel, payload):
    c = channel.encode()
    return struct.pack('>IqqII', SYNC, eventnum, 1700000000000000, len(c), len(payload)) + c + payload

events = []  # (offset, eventnum, channel, payload)
pos = 0
while pos < len(data):
    sync, eventnum, _, chanlen, datalen = struct.unpack('>Iqqii', data[pos:pos + 28])
    assert sync == SYNC
    channel = data[pos + 28:pos + 28 + chanlen].decode()
    events.append((pos, eventnum, channel, data[pos + 28 + chanlen:pos + 28 + chanlen + datalen]))
    pos += 28 + chanlen + datalen

def write(name, content, expect):
    open(f'{tmp}/{name}.lcmlog', 'wb').write(content)
    open(f'{tmp}/{name}.expect', 'w').write(expect)

def rewrite(change):  # the log with change(index, payload) -> payload
    return b''.join(event(n, c, change(i, p)) for i, (_, n, c, p) in enumerate(events))

def first(channel):
    return next(i for i, e in enumerate(events) if e[2] == channel)

# lcm-logger under scripts/launch records 7 self-test events of the UDP provider.
write('selftest', b''.join(event(i, 'LCM_SELF_TEST', b'lcm self test') for i in range(7)) + data,
      'LCM self-test: 7 events on LCM_SELF_TEST')

# A fingerprint nobody has, in the first event.
write('unknown', rewrite(lambda j, p: b'\x01\x02\x03\x04\x05\x06\x07\x08' + p[8:] if j == 0 else p),
      f'event #1 (eventnum {events[0][1]}, byte 0) on {events[0][2]}: no type with fingerprint 0102030405060708')

last, last_num, last_channel, last_payload = events[-1]
n = len(events)
write('cut_payload', data[:len(data) - len(last_payload) // 2],
      f'byte {last}: file ends inside event #{n} (eventnum {last_num} on {last_channel})')
write('cut_header', data[:last + 11],
      f'byte {last}: file ends inside the header of event #{n} (11 of 28 header bytes)')

# 9 bytes of garbage over the end of event 10's payload and event 11's sync word.
g = bytearray(data)
at = events[10][0]
g[at - 3:at + 6] = b'\x55' * 9
write('garbled', bytes(g),
      f'byte {at}: no LCM log event where event #11 should start (sync word 0x55555555, expected 0xEDA1DA01); '
      f'skipped {events[11][0] - at} bytes to the next event at byte {events[11][0]}')

# A landmark request whose strings and counts are all 0xff: -1 and worse.
i = first('SPY_LANDMARK_REQUEST_T')
write('undecodable', rewrite(lambda j, p: p[:8] + b'\xff' * (len(p) - 8) if j == i else p),
      f'event #{i + 1} (eventnum {events[i][1]}, byte {events[i][0]}) on SPY_LANDMARK_REQUEST_T: '
      f'payload of {len(events[i][3])} bytes does not decode as vslam.landmark_request_t')

# Four bytes more than the message: the bus rejects this, so must the check.
i = first('SPY_ODOMETRY_T')
write('left_over', rewrite(lambda j, p: p + b'\0\0\0\0' if j == i else p),
      f'event #{i + 1} (eventnum {events[i][1]}, byte {events[i][0]}) on SPY_ODOMETRY_T: '
      f'payload of {len(events[i][3]) + 4} bytes decodes as vslam.odometry_t with 4 bytes left over')

# Issue 19's request: num_ids = 500,000,000 and no ids after it.
def hostile(p):
    at = 16                                          # fingerprint, utime
    for _ in range(2):                               # requester, database_id
        at += 4 + struct.unpack('>i', p[at:at + 4])[0]
    at += 8                                          # since_revision
    return p[:at] + struct.pack('>i', 500000000)
i = first('SPY_LANDMARK_REQUEST_T')
write('hostile_count', rewrite(lambda j, p: hostile(p) if j == i else p),
      f'event #{i + 1} (eventnum {events[i][1]}, byte {events[i][0]}) on SPY_LANDMARK_REQUEST_T: '
      f'payload of {len(hostile(events[i][3]))} bytes does not decode as vslam.landmark_request_t')
PY

if ! spy_check "$tmp/selftest.lcmlog" > "$tmp/selftest.txt" 2>&1; then
  echo "FAIL: LCM's self-test events made the check fail" >&2
  cat "$tmp/selftest.txt" >&2
  exit 1
fi
grep -qF "$(cat "$tmp/selftest.expect")" "$tmp/selftest.txt"
if grep -q '^LCM_SELF_TEST ' "$tmp/selftest.txt"; then
  echo "FAIL: LCM_SELF_TEST listed as a vslam channel" >&2
  exit 1
fi

for damage in unknown cut_payload cut_header garbled undecodable left_over hostile_count; do
  if spy_check "$tmp/$damage.lcmlog" > "$tmp/$damage.txt" 2>&1; then
    echo "FAIL: $damage log passed the check" >&2
    cat "$tmp/$damage.txt" >&2
    exit 1
  fi
  if ! grep -qF "$(cat "$tmp/$damage.expect")" "$tmp/$damage.txt"; then
    echo "FAIL: $damage log: expected \"$(cat "$tmp/$damage.expect")\" in:" >&2
    cat "$tmp/$damage.txt" >&2
    exit 1
  fi
done
echo "PASS: lcm-spy decodes all $expected vslam types, LCM self-test events pass, and damaged logs fail"
