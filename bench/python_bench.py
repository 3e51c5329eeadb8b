#!/usr/bin/env python3
"""What the Python module costs, and viscd against SciPy's cKDTree, on a dense 100 000-sphere frame.

1. Overhead: the wall time of `Detector.detect()` seen from Python (arguments in, Frame and its
   pairs array out) against the C++ Detector::detect() call inside it (Frame.stats["detect_ms"],
   timed by the module around that call alone) and the sum of the stage times (stats["total_ms"]),
   frame after frame on a scene that moves a little between frames (the moves are not timed).
2. viscd against scipy.spatial.cKDTree at the same frame: the tree built from the centres, then
   query_pairs(r = 2 * the largest radius, output_type="ndarray"), then viscd's exact sphere test
   on those candidates (float32, as viscd tests). The kd-tree's pairs are not sorted in the timed
   part (viscd's are), which favours cKDTree; both pair sets are checked equal afterwards.
   cKDTree is single-threaded: viscd is timed with all cores (threads=0) and with threads=1, and
   with keep_order=False (every frame sorts its codes and rebuilds, as the kd-tree does) beside the
   default (which keeps the last frame's order while the scene moves little).

The scene is bench's "dense cube": radii uniform in [0.25, 0.75] in a cube holding 17% of its
volume in spheres (about 0.6 pairs per object), no camera, every object active.

3. `viscd.pairs_within(points, r)` against `cKDTree(points).query_pairs(r, output_type="ndarray")`
   (the tree's build included, its rows unsorted, viscd's sorted), with --pairs-within: uniform
   points at unit density, r = 0.78 (about one pair per point), at 10^4 .. 10^7 points; the sets
   are checked equal, except for pairs whose float32 and float64 distances straddle r.

usage: PYTHONPATH=build/release/python python3 bench/python_bench.py [--objects 100000] [--repeats 31]
       PYTHONPATH=build/release/python python3 bench/python_bench.py --pairs-within [--sizes 10000,...]
"""

import argparse
import datetime
import os
import platform
import statistics
import time

import numpy as np

import viscd


def dense_cube(n, seed):
    rng = np.random.default_rng(seed)
    r = rng.uniform(0.25, 0.75, n)
    side = (np.sum(4.0 / 3.0 * np.pi * r**3) / 0.17) ** (1.0 / 3.0)
    spheres = np.empty((n, 4), np.float32)
    spheres[:, :3] = rng.uniform(0, side, (n, 3))
    spheres[:, 3] = r
    return spheres, side


def exact_filter(spheres, cand):
    a, b = spheres[cand[:, 0]], spheres[cand[:, 1]]
    dx, dy, dz = a[:, 0] - b[:, 0], a[:, 1] - b[:, 1], a[:, 2] - b[:, 2]
    s = a[:, 3] + b[:, 3]
    return cand[dx * dx + dy * dy + dz * dz <= s * s]


def cpu_model():
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def median(xs):
    return statistics.median(xs)


def pairs_within_vs_kdtree(sizes, repeats, seed):
    from scipy.spatial import cKDTree
    import scipy

    r = 0.78
    print(f"\n3. viscd.pairs_within vs scipy {scipy.__version__} cKDTree(points).query_pairs(r={r}), "
          f"uniform points at unit density, threads = 0 ({os.cpu_count()} CPUs); medians of {repeats} runs after one")
    print(f"   {'points':>10} {'pairs':>10} {'pairs_within ms':>16} {'cKDTree ms':>12} {'cKDTree / viscd':>16}")
    for n in sizes:
        rng = np.random.default_rng(seed)
        points = rng.uniform(0, n ** (1.0 / 3.0), (n, 3)).astype(np.float32)
        ours, theirs = [], []
        for k in range(repeats + 1):
            t0 = time.perf_counter()
            got = viscd.pairs_within(points, r)
            t1 = time.perf_counter()
            kd = cKDTree(points).query_pairs(r, output_type="ndarray")
            t2 = time.perf_counter()
            if k:
                ours.append((t1 - t0) * 1e3)
                theirs.append((t2 - t1) * 1e3)
        kd = np.sort(kd, axis=1)
        kd = kd[np.lexsort((kd[:, 1], kd[:, 0]))].astype(np.uint32)
        differ = 0
        if not np.array_equal(got, kd):
            # viscd decides in float32, SciPy in float64: a pair may differ only where the two
            # roundings of the distance straddle r.
            key = lambda p: p[:, 0].astype(np.uint64) << np.uint64(32) | p[:, 1].astype(np.uint64)
            odd = np.setxor1d(key(got), key(kd))
            i, j = (odd >> np.uint64(32)).astype(np.int64), (odd & np.uint64(0xFFFFFFFF)).astype(np.int64)
            d = np.linalg.norm(points[i].astype(np.float64) - points[j].astype(np.float64), axis=1)
            worst = float(np.max(np.abs(d - r) / r))
            assert worst < 1e-5, f"{n} points: a pair {worst:.2e} of r from the threshold differs"
            differ = len(odd)
        a, b = median(ours), median(theirs)
        note = f"  ({differ} pairs differ, each within {worst:.1e} r of the threshold)" if differ else ""
        print(f"   {n:>10} {len(got):>10} {a:>16.2f} {b:>12.2f} {b / a:>15.1f}x{note}", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs-within", action="store_true", help="part 3 only: pairs_within against cKDTree")
    ap.add_argument("--sizes", default="10000,100000,1000000,10000000", help="point counts of part 3")
    ap.add_argument("--objects", type=int, default=100_000)
    ap.add_argument("--repeats", type=int, default=31, help="frames timed for the overhead (default 31)")
    ap.add_argument("--kdtree-repeats", type=int, default=7, help="timed runs of each method in part 2 (default 7)")
    ap.add_argument("--seed", type=int, default=7)
    args = ap.parse_args()

    print(f"date: {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC")
    print(f"machine: {cpu_model()}, {os.cpu_count()} logical CPUs, load average {os.getloadavg()[0]:.2f} at start")
    print(f"python {platform.python_version()}, numpy {np.__version__}, viscd {viscd.__version__}")
    if args.pairs_within:
        sizes = [int(x) for x in args.sizes.split(",")]
        pairs_within_vs_kdtree(sizes, min(args.kdtree_repeats, 3), args.seed)
        print(f"\nload average {os.getloadavg()[0]:.2f} at the end")
        return

    spheres, side = dense_cube(args.objects, args.seed)
    rng = np.random.default_rng(args.seed + 1)
    moves = rng.normal(0, 0.02, (4, args.objects, 3)).astype(np.float32)

    # ---- 1. the Python call against the C++ frame ----
    det = viscd.Detector()
    for _ in range(3):
        det.detect(spheres)
    py_ms, detect_ms, total_ms, pairs, kept = [], [], [], [], 0
    for k in range(args.repeats):
        spheres[:, :3] += moves[k % 4]
        t0 = time.perf_counter()
        frame = det.detect(spheres)
        p = frame.pairs
        t1 = time.perf_counter()
        st = frame.stats
        py_ms.append((t1 - t0) * 1e3)
        detect_ms.append(st["detect_ms"])
        total_ms.append(st["total_ms"])
        pairs.append(len(p))
        kept += st["order_kept"]
    overhead = [p - d for p, d in zip(py_ms, detect_ms)]
    print(f"\n1. overhead, {args.objects} spheres (side {side:.1f}), {median(pairs):.0f} pairs, "
          f"{args.repeats} frames, threads=0 ({os.cpu_count()} here)")
    print(f"   frames that kept the last order (no sort): {kept} of {args.repeats}")
    print(f"   Python detect() wall    median {median(py_ms):8.3f} ms")
    print(f"   C++ Detector::detect()  median {median(detect_ms):8.3f} ms")
    print(f"   sum of stage times      median {median(total_ms):8.3f} ms")
    print(f"   Python - C++            median {median(overhead):8.3f} ms = "
          f"{100 * median([o / d for o, d in zip(overhead, detect_ms)]):.2f}% of the C++ call, "
          f"{100 * median([(p - t) / t for p, t in zip(py_ms, total_ms)]):.2f}% over the stage sum")

    # ---- 2. viscd against cKDTree ----
    try:
        from scipy.spatial import cKDTree
    except ImportError:
        print("\n2. skipped: scipy is not installed (python3-scipy)")
        return
    import scipy

    rmax = float(spheres[:, 3].max())
    detectors = {
        "viscd threads=0": viscd.Detector(),
        "viscd threads=1": viscd.Detector(threads=1),
        # Every frame sorted and rebuilt, as the kd-tree is:
        "viscd threads=0, sorts": viscd.Detector(keep_order=False),
        "viscd threads=1, sorts": viscd.Detector(threads=1, keep_order=False),
    }
    times = {name: [] for name in detectors}
    times["cKDTree + exact test"] = []
    results = {}
    for k in range(args.kdtree_repeats + 1):  # the first run of each is a warm-up
        spheres[:, :3] += moves[k % 4]
        for name, d in detectors.items():
            t0 = time.perf_counter()
            results[name] = d.detect(spheres).pairs
            t = time.perf_counter() - t0
            if k:
                times[name].append(t * 1e3)
        t0 = time.perf_counter()
        tree = cKDTree(spheres[:, :3])
        cand = tree.query_pairs(2 * rmax, output_type="ndarray")
        kd = exact_filter(spheres, cand)
        t = time.perf_counter() - t0
        if k:
            times["cKDTree + exact test"].append(t * 1e3)
        kd_sorted = kd[np.lexsort((kd[:, 1], kd[:, 0]))].astype(np.uint32)
        for name in detectors:
            assert np.array_equal(results[name], kd_sorted), f"{name} and cKDTree disagree"
    print(f"\n2. viscd vs scipy {scipy.__version__} cKDTree.query_pairs(r={2 * rmax:.3f}) + exact test, "
          f"{args.objects} spheres, {len(kd)} pairs (identical), {args.kdtree_repeats} runs each")
    kd_ms = median(times["cKDTree + exact test"])
    for name, ts in times.items():
        print(f"   {name:24s} median {median(ts):9.2f} ms   (cKDTree / this: {kd_ms / median(ts):5.1f}x)")
    print(f"\nload average {os.getloadavg()[0]:.2f} at the end")


if __name__ == "__main__":
    main()
