#!/usr/bin/python3
"""scripts/benchmark-homes judges a start in a saved map in the map's frame,
cuts LCM logs by channel and time (the restarts' inputs), and counts the runs
after a carry in both frames.

    tests/launch/test_benchmark_homes.py REPO_ROOT

The map's frame is the SE(2) fit of its landmarks' poses onto the true robot
positions at their creation times (map_frame). A map that is the truth turned
and shifted, with a little noise, must give back that motion and a small rms;
a map with fewer than 3 placed landmarks gives none (the script then falls
back to the uninterrupted run's frame).
"""
import importlib.machinery
import importlib.util
import math
import sqlite3
import sys
import tempfile
from pathlib import Path

import numpy as np


def load_script(root):
    loader = importlib.machinery.SourceFileLoader("benchmark_homes",
                                                  f"{root}/scripts/benchmark-homes")
    spec = importlib.util.spec_from_loader("benchmark_homes", loader)
    module = importlib.util.module_from_spec(spec)
    loader.exec_module(module)
    return module


def write_map(path, rows):
    """A map file with the columns map_frame reads (the real schema has more)."""
    with sqlite3.connect(path) as db:
        db.execute("CREATE TABLE landmarks(landmark_id INTEGER PRIMARY KEY, "
                   "created_utime INTEGER NOT NULL, map_x REAL, map_y REAL)")
        db.executemany("INSERT INTO landmarks(created_utime, map_x, map_y) VALUES (?, ?, ?)",
                       rows)


def copy_events_failures(bh):
    """copy_events keeps the named channels' events from from_s to to_s (both
    included) after the log's first event, numbered again from 0."""
    failures = []
    with tempfile.TemporaryDirectory() as tmp:
        src, dst = Path(tmp) / "in.lcmlog", Path(tmp) / "out.lcmlog"
        with open(src, "wb") as f:
            for k in range(20):  # A and B in turn, every 0.5 s
                ch = b"A" if k % 2 == 0 else b"B"
                data = bytes([k])
                f.write(bh.struct.pack(">IqqiI", bh.LCM_SYNC, 100 + k, 1_000_000 + k * 500_000,
                                       len(ch), len(data)) + ch + data)
        bh.copy_events(src, dst, ("A",), from_s=2.0, to_s=5.0)
        got = []
        with open(dst, "rb") as f:
            while hdr := f.read(28):
                _, event, ts, clen, dlen = bh.struct.unpack(">IqqiI", hdr)
                ch = f.read(clen)
                got.append((event, (ts - 1_000_000) / 1e6, ch, f.read(dlen)[0]))
        want = [(n, 2.0 + n, b"A", 4 + 2 * n) for n in range(4)]
        if got != want:
            failures.append(f"copy_events A from 2 to 5 s gave {got}, not {want}")
    return failures


def runs_line_failures(bh):
    """runs_line counts every run against the target in the first run's frame,
    and the runs after a carry (run number 2 on) also in the map's own frame."""
    home = {"id": "home-1"}
    runs = [(home, 1, {"rmse_after_settle": 0.05, "rmse_after_settle_origin": 0.40}),
            (home, 2, {"rmse_after_settle": 0.20, "rmse_after_settle_origin": 0.06}),
            (home, 3, {"rmse_after_settle": 0.10, "rmse_after_settle_origin": 0.12}),
            (home, 2, {"rmse_after_settle": 0.30, "rmse_after_settle_origin": None})]
    line = bh.runs_line(runs)
    want = ("2 of 4 (of the 3 after a carry: 1 in the first run's frame, "
            "2 in the map's own frame from the true start pose)")
    failures = [] if line.endswith(want) else [f"runs line {line!r}, wanted it to end {want!r}"]
    single = bh.runs_line(runs[:1])
    if not single.endswith("1 of 1"):
        failures.append(f"without carries the line is {single!r}, not ending '1 of 1'")
    return failures


def main():
    bh = load_script(sys.argv[1])
    failures = []
    rng = np.random.default_rng(3)
    # The truth: a robot driving a loop, 10 Hz.
    ref_t = 1.7e9 + np.arange(0, 60, 0.1)
    ref_p = np.stack([3 + 2 * np.cos(ref_t / 10), 4 + 1.5 * np.sin(ref_t / 10),
                      np.zeros_like(ref_t)], axis=1)
    # The map: landmarks made every 5 s, in a frame turned by 25 deg and
    # shifted by (1, -2) from the truth's, each 2 cm off.
    th = math.radians(25)
    c, s = math.cos(th), math.sin(th)
    created = np.arange(20, 600, 50)
    truth = ref_p[created, :2]
    to_map = truth - np.array([1.0, -2.0])
    to_map = to_map @ np.array([[c, s], [-s, c]])  # turned by +25 deg: back is -25
    to_map += rng.normal(0, 0.02, to_map.shape)
    with tempfile.TemporaryDirectory() as tmp:
        good = Path(tmp) / "good.vslam-map"
        write_map(good, [(int(round(ref_t[k] * 1e6)), float(x), float(y))
                         for k, (x, y) in zip(created, to_map)]
                  + [(int(ref_t[5] * 1e6), None, None)])  # not placed: left out
        found = bh.map_frame(good, ref_t, ref_p)
        if found is None:
            failures.append("a map of 12 placed landmarks gave no frame")
        else:
            R, t, rms, n = found
            turn = math.degrees(math.atan2(R[1, 0], R[0, 0]))
            if abs(turn + 25) > 1.0:
                failures.append(f"the map's frame is turned back by {turn:.2f} deg, not -25")
            back = (np.c_[to_map, np.zeros(len(to_map))] @ R.T + t)[:, :2]
            worst = np.max(np.linalg.norm(back - truth, axis=1))
            if worst > 0.08:
                failures.append(f"landmarks {worst:.3f} m off the truth after the fit")
            if not 0.005 < rms < 0.05:
                failures.append(f"rms {rms:.4f} m for landmarks 2 cm off")
            if n != len(created):
                failures.append(f"{n} landmarks used, not the {len(created)} placed ones")
        sparse = Path(tmp) / "sparse.vslam-map"
        write_map(sparse, [(int(ref_t[k] * 1e6), float(x), float(y))
                           for k, (x, y) in zip(created[:2], to_map[:2])])
        if bh.map_frame(sparse, ref_t, ref_p) is not None:
            failures.append("a map of 2 placed landmarks gave a frame")
    failures += copy_events_failures(bh)
    failures += runs_line_failures(bh)
    for f in failures:
        print("FAIL:", f)
    if not failures:
        print("ok: benchmark-homes judges starts in the map's frame, cuts logs and counts runs")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
