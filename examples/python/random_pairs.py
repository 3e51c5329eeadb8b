#!/usr/bin/env python3
"""Every overlapping pair of a random scene, checked against a brute force on a sample.

From the build tree (after `cmake --build build/release`):
    PYTHONPATH=build/release/python python3 examples/python/random_pairs.py --objects 100000
"""

import argparse
import time

import numpy as np

import viscd


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--objects", type=int, default=100_000, help="number of spheres (default 100000)")
    ap.add_argument("--radius", type=float, default=0.5, help="largest radius (default 0.5)")
    ap.add_argument("--extent", type=float, default=100.0, help="the scene is a cube of this side (default 100)")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()

    rng = np.random.default_rng(args.seed)
    spheres = np.empty((args.objects, 4), np.float32)  # float32, C order: read without a copy
    spheres[:, :3] = rng.uniform(0, args.extent, (args.objects, 3))
    spheres[:, 3] = rng.uniform(0.1, 1.0, args.objects) * args.radius

    det = viscd.Detector()  # cpu backend, all cores; no camera: every object is active
    t0 = time.perf_counter()
    frame = det.detect(spheres)
    wall_ms = (time.perf_counter() - t0) * 1e3
    pairs = frame.pairs  # (P, 2) uint32, sorted, i < j
    colliding = np.count_nonzero(frame.state == 2)
    print(f"{args.objects} spheres: {len(pairs)} pairs, {colliding} colliding objects, "
          f"{wall_ms:.2f} ms (stages {frame.stats['total_ms']:.2f} ms, {frame.stats['bits']}-bit codes, "
          f"layout {frame.stats['layout']})")

    # Check the first 300 objects' pairs against a brute force in float32, as viscd tests.
    k = min(300, args.objects)
    c, r = spheres[:, :3], spheres[:, 3]
    for i in range(k):
        d = c - c[i]
        hits = np.nonzero((d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2]) <= (r + r[i]) ** 2)[0]
        expected = hits[hits > i]
        got = pairs[pairs[:, 0] == i, 1]
        assert np.array_equal(got, expected), f"object {i}: {got} != {expected}"
    print(f"pairs of the first {k} objects match a brute force")


if __name__ == "__main__":
    main()
