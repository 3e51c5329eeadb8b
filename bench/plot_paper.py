#!/usr/bin/env python3
"""Plots of `viscd bench paper`: fig6.png, fig7.png, fig8.png and table2.png from the CSVs.

Usage: python3 bench/plot_paper.py RESULTS_FOLDER
"""
import csv
import sys
from collections import defaultdict
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def rows(folder, name):
    with open(folder / name, newline="") as f:
        return list(csv.DictReader(f))


def series(data, key, x="objects", y="fps"):
    out = defaultdict(list)
    for r in data:
        out[(r["backend"], r[key])].append((int(r[x]), float(r[y])))
    return {k: sorted(v) for k, v in out.items()}


def line_plot(folder, name, data, key, title, ylabel, y="fps", logy=False):
    fig, ax = plt.subplots(figsize=(7, 4.2), dpi=110)
    for (backend, label), pts in sorted(series(data, key, y=y).items()):
        xs, ys = zip(*pts)
        ax.plot(xs, ys, marker="o", label=f"{backend}: {label}")
    ax.set_xscale("log")
    if logy:
        ax.set_yscale("log")
    ax.set_xlabel("objects N")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(folder / name)
    plt.close(fig)


def main():
    folder = Path(sys.argv[1])
    f6 = rows(folder, "fig6.csv")
    for r in f6:
        # "off" is the paper's baseline: every object, 64-bit codes, no visibility map.
        r["culling"] = "culling on" if r["culling"] == "on" else "culling off (64 bits, no map)"
    line_plot(folder, "fig6.png", f6, "culling", "Fig. 6: frames per second with and without culling (λ = 200)",
              "frames per second", logy=True)
    line_plot(folder, "fig7.png", rows(folder, "fig7.csv"), "mode",
              "Fig. 7: adaptive Morton bits against fixed 32 / 64 (a = 100, b = 400)", "frames per second", logy=True)
    f8 = rows(folder, "fig8.csv")
    for r in f8:
        r["mib"] = float(r["memory_bytes"]) / 2**20
        r["culling"] = "culling " + r["culling"]
    line_plot(folder, "fig8.png", f8, "culling", "Fig. 8: working memory against N", "MiB", y="mib", logy=True)

    t2 = rows(folder, "table2.csv")
    fig, ax = plt.subplots(figsize=(7, 4.2), dpi=110)
    groups = sorted({(r["backend"], r["objects"]) for r in t2})
    width = 0.8 / max(1, len(groups))
    for g, (backend, n) in enumerate(groups):
        pts = [r for r in t2 if r["backend"] == backend and r["objects"] == n]
        xs = [i + g * width for i in range(len(pts))]
        ax.bar(xs, [float(r["ratio_to_16"]) for r in pts], width, label=f"{backend}, N = {n}")
    ax.set_xticks([i + 0.4 - width / 2 for i in range(3)], ["16 bits", "32 bits", "64 bits"])
    ax.axhline(1.0, color="grey", lw=0.8)
    ax.set_ylabel("sort time / 16-bit sort time")
    ax.set_title("Table 2: sort time by Morton width (paper: 1 : 1.95 : 4.11)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(folder / "table2.png")
    plt.close(fig)
    print(f"plots written to {folder}: fig6.png fig7.png fig8.png table2.png")


if __name__ == "__main__":
    main()
