#!/usr/bin/env python3
"""Plots the FCL part of viscd_adapters_bench run one manager per process: each process's median
time for viscd::FclBroadphaseManager and fcl::DynamicAABBTreeCollisionManager, every box moving
and 1 % named, with the medians over processes and their ratio.

Usage: plot_fcl_processes.py RESULTS_TXT... [--out PNG] [--title TEXT]
Each file holds the output lines of `viscd_adapters_bench --only fcl --fcl-managers fcl` and
`... viscd` (the manager's name, then register+setup+collide, update+collide, update alone and
1 %-named+collide in ms); other lines are skipped.
"""

import argparse
import statistics

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (the backend must be chosen first)

MANAGERS = [
    ("viscd::", "viscd::FclBroadphaseManager", "tab:red"),
    ("fcl::", "fcl::DynamicAABBTreeCollisionManager", "tab:gray"),
]
COLUMNS = [(1, "every box moving: update() + collide()"), (3, "1 % named: update(vector) + collide()")]


def read(paths):
    times = {prefix: [] for prefix, _, _ in MANAGERS}
    for path in paths:
        with open(path, encoding="utf-8") as f:
            for line_no, line in enumerate(f, 1):
                fields = line.split()
                if not fields or not any(fields[0].startswith(p) for p in times):
                    continue
                try:
                    values = [float(v) for v in fields[1:5]]
                except ValueError as e:
                    raise SystemExit(f"{path}:{line_no}: expected four times in ms after the name: {e}") from e
                if len(values) != 4:
                    raise SystemExit(f"{path}:{line_no}: expected four times in ms after the name")
                prefix = next(p for p in times if fields[0].startswith(p))
                times[prefix].append(values)
    for prefix, name, _ in MANAGERS:
        if not times[prefix]:
            raise SystemExit(f"no {name} lines in {', '.join(paths)}")
    return times


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="+")
    ap.add_argument("--out", default="fcl_processes.png")
    ap.add_argument("--title", default="")
    args = ap.parse_args()
    times = read(args.files)

    fig, axes = plt.subplots(1, len(COLUMNS), figsize=(10, 4.2))
    for ax, (column, label) in zip(axes, COLUMNS):
        medians = {}
        for x, (prefix, name, colour) in enumerate(MANAGERS):
            values = [v[column] for v in times[prefix]]
            medians[prefix] = statistics.median(values)
            # Processes spread sideways in their order, so that equal times stay visible.
            xs = [x + 0.25 * (k / max(1, len(values) - 1) - 0.5) for k in range(len(values))]
            ax.scatter(xs, values, s=18, color=colour, alpha=0.8, label=f"{name} ({len(values)} processes)")
            ax.hlines(medians[prefix], x - 0.2, x + 0.2, color=colour, linewidth=2)
            ax.annotate(f"median {medians[prefix]:.1f} ms", (x + 0.22, medians[prefix]), va="center", fontsize=8)
        ratio = medians["fcl::"] / medians["viscd::"]
        ax.set_title(f"{label}\nFCL / viscd, medians: {ratio:.1f}x", fontsize=9)
        ax.set_xticks(range(len(MANAGERS)), ["viscd", "FCL DynamicAABBTree"])
        ax.set_xlim(-0.5, len(MANAGERS) - 0.3)
        ax.set_yscale("log")
        ax.set_ylabel("ms per frame, each process's median")
        ax.grid(True, axis="y", which="both", alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, fontsize=8, loc="lower center", ncol=len(MANAGERS))
    if args.title:
        fig.suptitle(args.title, fontsize=10)
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
