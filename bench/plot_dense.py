#!/usr/bin/env python3
"""Plots viscd_peers CSVs of the dense scenes: ms per frame by method, one panel per scene.

usage: plot_dense.py OUT.png LABEL=FILE.csv [LABEL=FILE.csv ...]
"""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    out, panels = sys.argv[1], [a.split("=", 1) for a in sys.argv[2:]]
    fig, axes = plt.subplots(1, len(panels), figsize=(5 * len(panels), 4), squeeze=False)
    for ax, (label, path) in zip(axes[0], panels):
        rows = list(csv.DictReader(open(path)))
        methods = list(dict.fromkeys(r["method"] for r in rows))
        sizes = sorted({int(r["objects"]) for r in rows})
        width = 0.8 / len(methods)
        for k, m in enumerate(methods):
            ms = [next((float(r["median_ms"]) for r in rows if r["method"] == m and int(r["objects"]) == n), 0)
                  for n in sizes]
            ax.bar([i + k * width for i in range(len(sizes))], ms, width, label=m)
        ax.set_xticks([i + 0.4 - width / 2 for i in range(len(sizes))])
        ax.set_xticklabels([f"N = {n:,}" for n in sizes])
        ax.set_yscale("log")
        ax.set_ylabel("median ms per frame (log)")
        ax.set_title(label)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=110)


if __name__ == "__main__":
    main()
