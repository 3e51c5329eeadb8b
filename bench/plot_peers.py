#!/usr/bin/env python3
"""Plots viscd_peers CSV output: median ms per frame against N, log-log, one line per method.

Usage: plot_peers.py PEERS_CSV [OUT_PNG] [--title TEXT]
The CSV has the columns method,objects,median_ms,min_ms,pairs,speedup_vs_viscd (viscd_peers --csv).
"""

import argparse
import csv
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (the backend must be chosen first)
import matplotlib.ticker  # noqa: E402

# Fixed colours and markers so that plots from different machines compare at a glance.
STYLE = {
    "viscd": ("tab:red", "o", "-"),
    "viscd_1t": ("tab:red", "o", "--"),
    "bullet_dbvt": ("tab:blue", "s", "-"),
    "bullet_sap": ("tab:cyan", "^", "-"),
    "fcl_dtree": ("tab:green", "D", "-"),
}
LABEL = {
    "viscd": "viscd cpu (all threads)",
    "viscd_1t": "viscd cpu (1 thread)",
    "bullet_dbvt": "Bullet btDbvtBroadphase",
    "bullet_sap": "Bullet bt32BitAxisSweep3",
    "fcl_dtree": "FCL DynamicAABBTreeCollisionManager",
}


def human(n):
    """2000 -> 2k, 1000000 -> 1M."""
    for div, suffix in ((1_000_000, "M"), (1_000, "k")):
        if n >= div and n % div == 0:
            return f"{n // div}{suffix}"
    return str(n)


def read_rows(path):
    series = defaultdict(list)
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            series[row["method"]].append((int(row["objects"]), float(row["median_ms"]), float(row["min_ms"])))
    for rows in series.values():
        rows.sort()
    return series


def main(argv):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("csv", help="viscd_peers --csv output")
    parser.add_argument("out", nargs="?", default="docs/peers.png", help="PNG to write (default docs/peers.png)")
    parser.add_argument("--title", default="Exact sphere pairs per frame, moving ring scene (lower is better)")
    parser.add_argument("--target-ms", type=float, default=10.0, help="draw a horizontal target line (0: none)")
    args = parser.parse_args(argv)

    series = read_rows(args.csv)
    if not series:
        sys.exit(f"{args.csv}: no rows")
    fig, ax = plt.subplots(figsize=(7.5, 5.0), dpi=120)
    order = [m for m in STYLE if m in series] + sorted(m for m in series if m not in STYLE)
    for method in order:
        rows = series[method]
        n = [r[0] for r in rows]
        med = [r[1] for r in rows]
        color, marker, line = STYLE.get(method, (None, "x", "-"))
        ax.plot(n, med, marker=marker, linestyle=line, color=color, label=LABEL.get(method, method))
    if args.target_ms > 0:
        ax.axhline(args.target_ms, color="gray", linestyle=":", linewidth=1)
        ax.annotate(f"{args.target_ms:g} ms target", (min(r[0] for s in series.values() for r in s), args.target_ms),
                    textcoords="offset points", xytext=(2, 4), fontsize=8, color="gray")
    ax.set_xscale("log")
    ax.set_yscale("log")
    sizes = sorted({r[0] for rows in series.values() for r in rows})
    ax.set_xticks(sizes, [human(n) for n in sizes])
    ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax.set_xlabel("objects N")
    ax.set_ylabel("median ms per frame (update + query)")
    ax.set_title(args.title, fontsize=10)
    ax.grid(True, which="both", linewidth=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main(sys.argv[1:])
