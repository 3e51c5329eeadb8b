#!/usr/bin/env python3
"""Plots viscd_mpi_bench CSV output (bench/mpi_scaling.sh): where a distributed frame's time goes
(the local frame, the rank's own passes of the exchange, its MPI calls) for each rank count and
size, and the halo share (ghosts a rank receives per own object) against the ranks.

Usage: plot_mpi.py SCALING_CSV [OUT_PNG] [--title TEXT] [--cores N]
Rows with the same (mode, ranks, objects) are repeats: their medians are drawn. Rank counts above
--cores ran oversubscribed: their times are greyed out and marked, their halo shares hold.
"""

import argparse
import csv
import statistics
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (the backend must be chosen first)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("csv")
    ap.add_argument("out", nargs="?", default="mpi_scaling.png")
    ap.add_argument("--title", default="")
    ap.add_argument("--cores", type=int, default=2)
    args = ap.parse_args()
    groups = defaultdict(list)
    with open(args.csv, newline="") as f:
        for r in csv.DictReader(f):
            groups[(r["mode"], int(r["ranks"]), int(r["objects"]))].append(r)

    def med(rows, col):
        return statistics.median(float(r[col]) for r in rows)

    keys = sorted(groups, key=lambda k: (k[0], k[2], k[1]))
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(13, 4.6), gridspec_kw={"width_ratios": [2.2, 1]})
    labels, local, own, comm = [], [], [], []
    for mode, ranks, objects in keys:
        rows = groups[(mode, ranks, objects)]
        frame, exch, c, det = (med(rows, k) for k in ("frame_ms", "exchange_ms", "communication_ms", "detect_ms"))
        labels.append(f"{mode}\n{objects:.0e}\n{ranks} rank{'s' if ranks > 1 else ''}"
                      + ("\n(oversub.)" if ranks > args.cores else ""))
        local.append(det / frame * 100)
        own.append(max(exch - c, 0) / frame * 100)
        comm.append(c / frame * 100)
    x = range(len(labels))
    ax.bar(x, local, color="tab:blue", label="local frame (own + ghosts)")
    ax.bar(x, own, bottom=local, color="tab:orange", label="exchange: the rank's own passes (checks, region, selection)")
    ax.bar(x, comm, bottom=[a + b for a, b in zip(local, own)], color="tab:red", label="exchange: MPI calls")
    ax.set_xticks(list(x))
    ax.set_xticklabels(labels, fontsize=7)
    ax.set_ylabel("% of the slowest rank's frame")
    ax.set_ylim(0, 105)
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title("Where a distributed frame's time goes")

    by_n = defaultdict(list)
    for mode, ranks, objects in keys:
        if mode == "strong":
            by_n[objects].append((ranks, med(groups[(mode, ranks, objects)], "halo_share") * 100))
    for objects, pts in sorted(by_n.items()):
        pts.sort()
        bx.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", label=f"{objects:.0e} objects")
    bx.set_xscale("log", base=2)
    bx.set_xlabel("ranks (slabs along x)")
    bx.set_ylabel("ghosts received per own object, %")
    bx.set_title("Halo share, strong scaling")
    bx.legend(fontsize=8)
    bx.grid(alpha=0.3)
    if args.title:
        fig.suptitle(args.title, fontsize=10)
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
