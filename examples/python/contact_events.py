#!/usr/bin/env python3
"""Contact events over a moving scene: which pairs began and ended touching each frame.

Spheres drift through a box and bounce off its walls; with contact_events=True each frame
reports Frame.began and Frame.ended besides Frame.pairs. The script checks each frame's events
against the difference of consecutive pair lists and prints a line per frame.

From the build tree:
    PYTHONPATH=build/release/python python3 examples/python/contact_events.py --frames 20
"""

import argparse

import numpy as np

import viscd


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--objects", type=int, default=20_000)
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--seed", type=int, default=3)
    args = ap.parse_args()

    rng = np.random.default_rng(args.seed)
    n, side = args.objects, 100.0
    spheres = np.empty((n, 4), np.float32)
    spheres[:, :3] = rng.uniform(0, side, (n, 3))
    spheres[:, 3] = rng.uniform(0.2, 0.8, n)
    velocity = rng.normal(0, 0.3, (n, 3)).astype(np.float32)

    det = viscd.Detector(contact_events=True)
    previous = np.zeros((0, 2), np.uint32)
    for frame_no in range(args.frames):
        frame = det.detect(spheres)
        # began/ended are sorted (i, j) arrays; as sets of 64-bit keys they are easy to check.
        key = lambda p: p[:, 0].astype(np.uint64) << np.uint64(32) | p[:, 1].astype(np.uint64)  # noqa: E731
        assert np.array_equal(key(frame.began), np.setdiff1d(key(frame.pairs), key(previous)))
        assert np.array_equal(key(frame.ended), np.setdiff1d(key(previous), key(frame.pairs)))
        print(f"frame {frame_no:3d}: {len(frame.pairs):6d} pairs, {len(frame.began):5d} began, "
              f"{len(frame.ended):5d} ended")
        previous = frame.pairs
        spheres[:, :3] += velocity
        out = (spheres[:, :3] < 0) | (spheres[:, :3] > side)
        velocity[out] *= -1


if __name__ == "__main__":
    main()
