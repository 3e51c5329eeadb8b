#!/usr/bin/env python3
"""Time and memory of `viscd run` (cpu backend) against N, from 10^3 to 10^7 objects.

Three series: the ring without culling (packing 0.04), the dense ring without culling (0.18),
and the ring with culling (zoom-out camera: the map is rendered and counted). Each point is the
median over --repeats runs of the median detector time per frame (a frame's stage times summed:
the scene's own simulation step left out) and of the peak resident memory the frames add to the
process, per object (`viscd run`'s "memory" line: the screenshot frame left out).

usage: scale.py [--viscd build/release/viscd] [--repeats 3] [--max 10000000] --csv OUT.csv --png OUT.png
       scale.py --plot-only --csv IN.csv --png OUT.png
"""
import argparse
import csv
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile

SIZES = [1000, 3000, 10000, 30000, 100000, 300000, 1000000, 3000000, 10000000]
SERIES = [
    ("ring, no culling", ["--no-culling", "--packing", "0.04"]),
    ("dense ring, no culling", ["--no-culling", "--packing", "0.18"]),
    ("ring, culling (zoom-out)", ["--packing", "0.04"]),
]


def frames_for(n):
    # About 3 * 10^7 object-frames per run, at least 8 frames and at most 200.
    return max(8, min(200, 30_000_000 // n))


def run_once(viscd, n, extra):
    with tempfile.TemporaryDirectory() as out:
        cmd = [viscd, "run", "--quiet", "--objects", str(n), "--frames", str(frames_for(n)), "--out", out] + extra
        subprocess.run(cmd, check=True)
        summary = json.load(open(os.path.join(out, "summary.json")))
        rows = list(csv.DictReader(open(os.path.join(out, "frames.csv"))))
    # The frames before the screenshot's (that one also shades), past the first (it allocates).
    detector = [float(r["frame_ms"]) - float(r["simulate_ms"]) for r in rows[1:-1]] or [
        float(r["frame_ms"]) - float(r["simulate_ms"]) for r in rows
    ]
    mem = summary.get("memory", {})
    return statistics.median(detector), mem.get("added_bytes_per_object"), summary["last_frame"]


def measure(args):
    sizes = [n for n in SIZES if n <= args.max]
    with open(args.csv, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["series", "objects", "frames", "detector_ms", "bytes_per_object", "bits", "pairs", "active"])
        for n in sizes:
            for name, extra in SERIES:
                ms, mem = [], []
                for _ in range(args.repeats):
                    t, b, last = run_once(args.viscd, n, extra)
                    ms.append(t)
                    if b is not None:
                        mem.append(b)
                row = [name, n, frames_for(n), f"{statistics.median(ms):.4f}",
                       f"{statistics.median(mem):.1f}" if mem else "", last["bits"], last["pairs"], last["active"]]
                w.writerow(row)
                f.flush()
                print(f"{name:26s} N={n:>9,d}  {statistics.median(ms):10.3f} ms  "
                      f"{row[4] or '-':>6s} B/object  m={last['bits']}", file=sys.stderr)


def plot(args):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = list(csv.DictReader(open(args.csv)))
    fig, (ax_t, ax_m) = plt.subplots(1, 2, figsize=(11, 4.2))
    for name, _ in SERIES:
        pts = [(int(r["objects"]), float(r["detector_ms"]), r["bytes_per_object"]) for r in rows if r["series"] == name]
        if not pts:
            continue
        ns = [p[0] for p in pts]
        line, = ax_t.plot(ns, [p[1] for p in pts], "o-", label=name)
        mem = [(p[0], float(p[2])) for p in pts if p[2] and p[0] >= 100000]
        if mem:
            ax_m.plot([m[0] for m in mem], [m[1] for m in mem], "o-", color=line.get_color(), label=name)
    # N log N through the first series' 10^6 point, for the eye.
    first = [r for r in rows if r["series"] == SERIES[0][0]]
    at = next((r for r in first if int(r["objects"]) == 1000000), None)
    if at:
        ref = float(at["detector_ms"]) / (1e6 * math.log(1e6))
        ns = [int(r["objects"]) for r in first if int(r["objects"]) >= 100000]
        ax_t.plot(ns, [ref * n * math.log(n) for n in ns], "k:", label="N log N (through the ring at 10^6)")
    ax_t.set_xscale("log")
    ax_t.set_yscale("log")
    ax_t.set_xlabel("objects N")
    ax_t.set_ylabel("median detector ms per frame")
    ax_t.set_title("Time per frame (cpu, 2 threads)")
    ax_t.legend(fontsize=8)
    ax_m.axhline(96, color="k", ls=":", label="96 bytes per object")
    ax_m.set_xscale("log")
    ax_m.set_ylim(0, None)
    ax_m.set_xlabel("objects N")
    ax_m.set_ylabel("peak memory added by the frames, bytes per object")
    ax_m.set_title("Peak memory (N >= 10^5)")
    ax_m.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(args.png, dpi=110)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--viscd", default="build/release/viscd")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--max", type=int, default=10000000)
    p.add_argument("--csv", required=True)
    p.add_argument("--png", required=True)
    p.add_argument("--plot-only", action="store_true")
    args = p.parse_args()
    if not args.plot_only:
        measure(args)
    plot(args)


if __name__ == "__main__":
    main()
