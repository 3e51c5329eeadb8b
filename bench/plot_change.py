#!/usr/bin/env python3
"""Plots viscd_change_bench --fractions CSV output: a frame's time over the rebuild of a frame in
which every object moves, against the fraction that moves, one panel per shape.

Usage: plot_change.py CHANGE_CSV [OUT_PNG] [--title TEXT]
The CSV has the columns shape,objects,fraction,mode,rebuild_ms,compared_ms,listed_ms,all_moving_ms,pairs
(viscd_change_bench --fractions --csv). A fraction of 0 is drawn at the left edge, marked "0".
"""

import argparse
import csv
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (the backend must be chosen first)

SERIES = [
    ("rebuild_ms", "rebuild every frame (follow_change off)", "tab:gray", "s", "--"),
    ("compared_ms", "follow change, bounds compared", "tab:red", "o", "-"),
    ("listed_ms", "follow change, FrameInput::moved given", "tab:blue", "^", "-"),
]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("csv")
    ap.add_argument("out", nargs="?", default="change.png")
    ap.add_argument("--title", default="")
    args = ap.parse_args()
    rows = defaultdict(list)
    with open(args.csv, newline="") as f:
        for r in csv.DictReader(f):
            rows[(r["shape"], r["objects"])].append(r)
    keys = sorted(rows)
    fig, axes = plt.subplots(1, len(keys), figsize=(5.2 * len(keys), 4.2), squeeze=False)
    zero_at = 3e-4
    for ax, key in zip(axes[0], keys):
        data = sorted(rows[key], key=lambda r: float(r["fraction"]))
        xs = [max(float(r["fraction"]), zero_at) for r in data]
        for column, label, colour, marker, style in SERIES:
            ys = [float(r[column]) / float(r["all_moving_ms"]) for r in data]
            ax.plot(xs, ys, color=colour, marker=marker, linestyle=style, label=label)
        ax.axhline(0.10, color="tab:green", linewidth=0.8, linestyle=":", label="target 0.10 (1 % moving)")
        ax.axhline(0.05, color="tab:olive", linewidth=0.8, linestyle=":", label="target 0.05 (1 %, moved given)")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ticks = [zero_at, 1e-3, 1e-2, 5e-2, 1.0]
        ax.set_xticks(ticks)
        ax.set_xticklabels(["0", "0.1 %", "1 %", "5 %", "100 %"])
        ax.set_xlabel("objects that move each frame")
        ax.set_ylabel("frame time / rebuild of an all-moving frame")
        shape, objects = key
        plural = {"sphere": "spheres", "box": "boxes"}.get(shape, shape)
        ax.set_title(f"{int(objects):,} {plural}".replace(",", " "))
        ax.grid(True, which="both", alpha=0.3)
    axes[0][0].legend(fontsize=7, loc="lower right")
    if args.title:
        fig.suptitle(args.title, fontsize=9)
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)


if __name__ == "__main__":
    main()
