#!/usr/bin/env python3
"""The gl backend's work against the active count, and its sort's time per radix pass.

Runs `viscd run --backend gl` (on llvmpipe these are CPU timings: compare ratios only) for two
binaries or one, interleaved, and prints medians over the runs of each configuration's median
frame (the tool's frames CSV; the first frames, which wait mid-frame, are skipped).

  bench/gl_lean.py active  VISCD [VISCD_OLD]   # culled zoom-out frames: broadphase ms vs N
  bench/gl_lean.py passes  VISCD [VISCD_OLD]   # no culling: sort ms / passes at 16 and 64 bits
"""
import csv
import statistics
import subprocess
import sys
import tempfile

BROADPHASE = ["codes_ms", "sort_ms", "build_ms", "fit_ms", "query_ms"]


def frames(viscd, args):
    with tempfile.TemporaryDirectory() as out:
        subprocess.run([viscd, "run", "--backend", "gl", "--quiet", "--out", out] + args, check=True)
        with open(f"{out}/frames.csv") as f:
            rows = list(csv.DictReader(f))
    return rows[3:]  # timers arrive a frame late; the first frames run in sync mode


def median_of(rows, columns):
    return statistics.median(sum(float(r[c]) for c in columns) for r in rows)


def main():
    mode, binaries = sys.argv[1], sys.argv[2:]
    runs = 5
    if mode == "active":
        configs = [(n, ["--objects", str(n), "--frames", "20"]) for n in (1000, 20000)]
        columns = BROADPHASE
    elif mode == "passes":
        configs = [((n, bits), ["--objects", str(n), "--no-culling", "--bits", str(bits), "--frames", "8",
                                "--size", "640x360"]) for n in (10000, 100000) for bits in (16, 64)]
        columns = ["sort_ms"]
    else:
        sys.exit(__doc__)
    results = {}
    for _ in range(runs):  # interleaved: every binary and configuration once per round
        for key, args in configs:
            for b in binaries:
                rows = frames(b, args)
                results.setdefault((b, key), []).append(median_of(rows, columns))
                if mode == "active":
                    results.setdefault((b, key, "active"), []).append(statistics.median(int(r["active"]) for r in rows))
    for b in binaries:
        print(b)
        for key, _ in configs:
            ms = statistics.median(results[(b, key)])
            if mode == "active":
                act = statistics.median(results[(b, key, "active")])
                print(f"  N = {key:6d}: {act:6.0f} active, broadphase (codes..query) {ms:8.3f} ms")
            else:
                n, bits = key
                print(f"  N = {n:6d}, m = {bits}: sort {ms:9.3f} ms, {ms / (bits // 8):8.3f} ms per pass")
        if mode == "active":
            a, b2 = (statistics.median(results[(b, key)]) for key, _ in configs)
            print(f"  ratio 20000 / 1000: {b2 / a:.2f}")


if __name__ == "__main__":
    main()
