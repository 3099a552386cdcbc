"""Reading LCM logs from the scripts: the events of a log and the fields of
the messages the scripts look into (big-endian, in the .lcm files' order)."""

import struct


def read_lcm_log(path):
    """Yields (recv_utime, channel, payload) of every event of an LCM log."""
    with open(path, "rb") as f:
        data = f.read()
    pos, n = 0, len(data)
    while pos + 28 <= n:
        sync, _num, utime, clen, dlen = struct.unpack_from(">IqqII", data, pos)
        if sync != 0xEDA1DA01:
            raise ValueError(f"{path}: bad sync word at byte {pos}")
        pos += 28
        if pos + clen + dlen > n:
            break  # the logger was stopped mid-event
        channel = data[pos:pos + clen].decode("ascii", "replace")
        pos += clen
        yield utime, channel, data[pos:pos + dlen]
        pos += dlen


class Reader:
    """Big-endian LCM fields in order; skips the 8-byte type fingerprint."""

    def __init__(self, data):
        self.d, self.p = data, 8

    def _get(self, fmt):
        v = struct.unpack_from(fmt, self.d, self.p)[0]
        self.p += struct.calcsize(fmt)
        return v

    def i8(self):
        return self._get(">b")

    def i32(self):
        return self._get(">i")

    def i64(self):
        return self._get(">q")

    def f64(self):
        return self._get(">d")

    def string(self):
        n = self.i32()
        s = self.d[self.p:self.p + n - 1].decode("utf-8", "replace")
        self.p += n
        return s


def decode_health(data):
    r = Reader(data)
    utime, process, instance, host, pid = r.i64(), r.string(), r.string(), r.string(), r.i32()
    uptime, level, message = r.f64(), r.i8(), r.string()
    cpu, rss, received, published, dropped = r.f64(), r.i64(), r.i64(), r.i64(), r.i64()
    malformed, latency_ms, n = r.i64(), r.f64(), r.i32()
    metrics = {}
    for _ in range(n):  # nested structs carry no fingerprint
        name, value, _unit = r.string(), r.f64(), r.string()
        metrics[name] = value
    return dict(utime=utime, process=process, instance=instance, host=host, pid=pid, uptime=uptime,
                level=level, message=message, cpu=cpu, rss=rss, received=received,
                published=published, dropped=dropped, malformed=malformed,
                latency_ms=latency_ms, metrics=metrics)
