#!/usr/bin/env python3
"""Plots of the GPU runs (bench/gpu/device_run.sh) for docs/gpu.md: gpu_stages.png, gpu_paper.png.

Usage: /usr/bin/python3 bench/plot_gpu.py RESULTS_DIR DOCS_DIR [CUDA_RESULTS_DIR]

With CUDA_RESULTS_DIR (its cuda_bench.csv, `viscd_cuda_bench` output) also gpu_cuda.png: the dense
scene's broadphase against N for cpu, gl and cuda, and the cuda frame's parts.

RESULTS_DIR holds stages_{ring,dense}_{gl,cpu}_N.json (`viscd run --no-culling --bits 32`
summaries) and paper_gl/ (`viscd bench paper --backend gl`: fig6.csv, table2.csv).
"""
import csv
import json
import re
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

STAGES = ["cull", "layout", "codes", "sort", "build", "fit", "query"]  # "simulate" is the demo's, not detect()'s
COLOURS = dict(zip(STAGES, plt.rcParams["axes.prop_cycle"].by_key()["color"]))
PAPER_SORT_US = {16: 98.13, 32: 191.1, 64: 403.3}  # the paper's Table 2 (RTX 3080)


def stage_runs(folder):
    """{(scene, backend): {N: median_ms dict}} from the stages_*.json files."""
    runs = {}
    for path in folder.glob("stages_*_*_*.json"):
        m = re.fullmatch(r"stages_(\w+)_(gl|cpu)_(\d+)\.json", path.name)
        if m:
            runs.setdefault((m[1], m[2]), {})[int(m[3])] = json.loads(path.read_text())["median_ms"]
    return runs


def plot_stages(folder, out):
    runs = stage_runs(folder)
    scenes = [s for s in ("ring", "dense") if (s, "gl") in runs or (s, "cpu") in runs]
    fig, axes = plt.subplots(len(scenes), 2, figsize=(11, 4.2 * len(scenes)), dpi=110, sharex=True, sharey=True,
                             squeeze=False)
    for row, scene in zip(axes, scenes):
        for ax, backend in zip(row, ("gl", "cpu")):
            by_n = runs.get((scene, backend), {})
            sizes = sorted(by_n)
            for stage in STAGES:
                pts = [(n, by_n[n][stage]) for n in sizes if by_n[n].get(stage, 0) > 0]
                if pts:
                    ax.plot(*zip(*pts), marker="o", color=COLOURS[stage], label=stage)
            total = [(n, sum(by_n[n].get(s, 0) for s in STAGES)) for n in sizes]
            if total:
                ax.plot(*zip(*total), "k--", marker="s", label="sum of stages")
            who = "gl: H100, GPU timer queries" if backend == "gl" else "cpu: 16 cores, host clock"
            ax.set_title(f"{scene} (packing {'0.04' if scene == 'ring' else '0.18'}), {who}", fontsize=10)
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.grid(True, which="both", alpha=0.3)
            ax.set_xlabel("objects N (all active, 32-bit codes)")
            ax.set_ylabel("median ms per frame")
            ax.legend(fontsize=8)
    fig.suptitle("detect() stage by stage; cpu keeps the last order, so its codes and sort medians are 0", fontsize=10)
    fig.tight_layout()
    fig.savefig(out)
    plt.close(fig)


def rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def plot_paper(folder, out):
    fig, (left, right) = plt.subplots(1, 2, figsize=(12, 4.4), dpi=110)
    f6 = rows(folder / "paper_gl" / "fig6.csv")
    for culling, label in (("on", "culling on (adaptive bits)"), ("off", "culling off (64 bits, no map)")):
        pts = sorted((int(r["objects"]), float(r["frame_ms"])) for r in f6 if r["culling"] == culling)
        left.plot(*zip(*pts), marker="o", label=label)
    left.set_xscale("log")
    left.set_yscale("log")
    left.set_xlabel("objects N")
    left.set_ylabel("median ms per frame (scene step + detect, wall clock)")
    left.set_title("Fig. 6 on the H100 (gl, zoom-out, λ = 200)", fontsize=10)
    left.grid(True, which="both", alpha=0.3)
    left.legend(fontsize=8)

    t2 = rows(folder / "paper_gl" / "table2.csv")
    groups = [(f"H100 gl, N = {n}", {int(r["bits"]): float(r["sort_ms"]) * 1000 for r in t2 if r["objects"] == n})
              for n in sorted({r["objects"] for r in t2}, key=int)]
    groups.append(("paper, RTX 3080", PAPER_SORT_US))
    width = 0.8 / len(groups)
    for g, (label, us) in enumerate(groups):
        xs = [i + g * width for i in range(3)]
        bars = right.bar(xs, [us[b] for b in (16, 32, 64)], width, label=label)
        right.bar_label(bars, fmt="%.0f", fontsize=7)
    right.set_xticks([i + 0.4 - width / 2 for i in range(3)], ["16 bits", "32 bits", "64 bits"])
    right.set_ylabel("radix sort of the Morton codes, µs")
    right.set_title("Table 2: sort time by Morton width", fontsize=10)
    right.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out)
    plt.close(fig)


def plot_cuda(folder, cuda_folder, out):
    """Dense scene, every object active, 32 bits: stage sums of cpu and gl (`viscd run`) against
    cuda's GPU-resident part and its detect() wall time (viscd_cuda_bench); cuda's parts as bars."""
    runs = stage_runs(folder)
    bench = [r for r in rows(cuda_folder / "cuda_bench.csv") if r["part"] == "dense"]
    fig, (a, b) = plt.subplots(1, 2, figsize=(12, 4.6))
    for backend, style in (("cpu", "s-"), ("gl", "o-")):
        pts = sorted(runs.get(("dense", backend), {}).items())
        a.plot([n for n, _ in pts], [sum(m[s] for s in STAGES) for _, m in pts], style,
               label=f"{backend}: stage sum" + (" (16 cores)" if backend == "cpu" else " (GPU timers)"))
    ns = [int(r["objects"]) for r in bench]
    a.plot(ns, [float(r["on_gpu_ms"]) for r in bench], "^-", label="cuda: on the GPU (codes ... pair sort)")
    a.plot(ns, [float(r["detect_ms"]) for r in bench], "v--", label="cuda: detect() wall, transfers included")
    a.set(xscale="log", yscale="log", xlabel="objects N (dense ring, 0.6 pairs/object)", ylabel="ms",
          title="Broadphase of every object, H100 vs 16 cores")
    a.grid(True, which="both", alpha=0.3)
    a.legend(fontsize=8)
    parts = ["codes", "sort", "build", "fit", "query", "pair_sort", "upload", "download"]
    totals = [sum(float(r[p + "_ms"]) for p in parts) for r in bench]
    bottom = [0.0] * len(bench)
    xs = list(range(len(bench)))
    for part in parts:
        vals = [100 * float(r[part + "_ms"]) / t for r, t in zip(bench, totals)]
        b.bar(xs, vals, bottom=bottom, label=part.replace("_", " "), hatch="//" if part in ("upload", "download") else None)
        bottom = [x + y for x, y in zip(bottom, vals)]
    for x, t in zip(xs, totals):
        b.annotate(f"{t:.3g} ms", (x, 101), ha="center", fontsize=8)
    b.set_xticks(xs, [f"{n:,}" for n in ns])
    b.set(ylim=(0, 110), xlabel="objects N", ylabel="% of the GPU events' sum",
          title="cuda frame by part (hatched: PCIe transfers)")
    b.legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    fig.savefig(out)
    plt.close(fig)


def main():
    if len(sys.argv) not in (3, 4):
        sys.exit(__doc__)
    folder, docs = Path(sys.argv[1]), Path(sys.argv[2])
    plot_stages(folder, docs / "gpu_stages.png")
    plot_paper(folder, docs / "gpu_paper.png")
    print(f"wrote {docs / 'gpu_stages.png'} and {docs / 'gpu_paper.png'}")
    if len(sys.argv) == 4:
        plot_cuda(folder, Path(sys.argv[3]), docs / "gpu_cuda.png")
        print(f"wrote {docs / 'gpu_cuda.png'}")


if __name__ == "__main__":
    main()
