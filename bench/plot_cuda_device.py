#!/usr/bin/env python3
"""The cuda backend's device-resident frame against its host call (docs/gpu.md, "Device-resident
frames"): from a viscd_cuda_bench CSV, the dense ring's GPU time per frame of CudaBroadphase (on a
stream, and replayed as a CUDA graph), the host call's kernels (codes to pair sort) and detect()'s
wall time, against N.

Usage: /usr/bin/python3 bench/plot_cuda_device.py CSV OUT.png   (Debian's python3-matplotlib)
"""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main() -> None:
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    rows = list(csv.DictReader(open(sys.argv[1])))
    dense = [r for r in rows if r["part"] == "dense"]
    device = [r for r in rows if r["part"] == "device"]
    if not dense or not device:
        sys.exit(f"{sys.argv[1]}: needs the dense and device parts")
    fig, ax = plt.subplots(figsize=(7, 4.5))

    def line(part, key, label, style):
        ax.plot([int(r["objects"]) for r in part], [float(r[key]) for r in part], style, label=label)

    line(dense, "detect_ms", "detect() from host arrays (wall)", "o-")
    line(dense, "on_gpu_ms", "detect()'s kernels (codes to pair sort)", "s--")
    line(device, "stream_gpu_ms", "CudaBroadphase on a stream (GPU)", "^-")
    line(device, "graph_gpu_ms", "CudaBroadphase as a CUDA graph (GPU)", "v-")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("objects (dense ring, 0.6 pairs an object, every object active, 32-bit codes)")
    ax.set_ylabel("ms per frame (median)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    ax.set_title("cuda backend on an NVIDIA H200, 2026-11-27")
    fig.tight_layout()
    fig.savefig(sys.argv[2], dpi=110)


if __name__ == "__main__":
    main()
