#!/usr/bin/env python3
"""A granular pile: grains poured into a box, stepped in NumPy with viscd's pairs as contacts.

Each step: viscd finds the touching grains; NumPy applies a spring-dashpot force along each
pair's normal, gravity and the walls, then integrates (semi-implicit Euler). Writes a PNG of
the pile (side view, colour = contacts per grain). The grains have no friction, so the pile
flattens into a bed as it settles.

From the build tree:
    PYTHONPATH=build/release/python python3 examples/python/granular_pile.py --out pile.png
"""

import argparse
import time

import numpy as np

import viscd


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grains", type=int, default=3000)
    ap.add_argument("--steps", type=int, default=2500)
    ap.add_argument("--out", default="granular_pile.png", help="PNG to write (default granular_pile.png)")
    ap.add_argument("--seed", type=int, default=2)
    args = ap.parse_args()

    rng = np.random.default_rng(args.seed)
    n = args.grains
    width, depth = 30.0, 6.0  # the box: x in [0, width], z in [0, depth], floor at y = 0
    radius = rng.uniform(0.35, 0.5, n).astype(np.float32)
    # Poured from a jittered lattice 1.05 apart, so that no two grains start overlapping.
    gx, gz = np.arange(0.6, width - 0.5, 1.05), np.arange(0.6, depth - 0.5, 1.05)
    layer = np.array([(x, z) for x in gx for z in gz])
    cell = np.arange(n)
    pos = np.column_stack([layer[cell % len(layer), 0], 3.0 + 1.05 * (cell // len(layer)),
                           layer[cell % len(layer), 1]]).astype(np.float32)
    pos[:, [0, 2]] += rng.uniform(-0.02, 0.02, (n, 2)).astype(np.float32)
    vel = np.zeros((n, 3), np.float32)
    mass = radius**3 / 0.125  # density 1 for r = 0.5 -> mass 1
    stiffness, damping, gravity, dt = 4000.0, 8.0, 9.81, 2e-3

    det = viscd.Detector()
    spheres = np.empty((n, 4), np.float32)
    spheres[:, 3] = radius
    contacts = np.zeros(n)
    detect_s = 0.0
    t0 = time.perf_counter()
    for _ in range(args.steps):
        spheres[:, :3] = pos
        t = time.perf_counter()
        pairs = det.detect(spheres).pairs
        detect_s += time.perf_counter() - t
        i, j = pairs[:, 0], pairs[:, 1]
        d = pos[j] - pos[i]
        dist = np.sqrt(np.einsum("ij,ij->i", d, d)) + 1e-12
        normal = d / dist[:, None]
        overlap = radius[i] + radius[j] - dist
        closing = np.einsum("ij,ij->i", vel[i] - vel[j], normal)
        f = np.maximum(stiffness * overlap + damping * closing, 0.0)[:, None] * normal  # push i away from j
        force = np.zeros((n, 3), np.float64)
        for axis in range(3):
            force[:, axis] = np.bincount(j, f[:, axis], n) - np.bincount(i, f[:, axis], n)
        force[:, 1] -= gravity * mass
        # Walls and floor: the same spring-dashpot against planes.
        for axis, lo, hi in ((0, 0.0, width), (1, 0.0, np.inf), (2, 0.0, depth)):
            below = np.maximum(lo + radius - pos[:, axis], 0)
            above = np.maximum(pos[:, axis] + radius - hi, 0)
            force[:, axis] += stiffness * (below - above) - damping * vel[:, axis] * ((below > 0) | (above > 0))
        vel += (force / mass[:, None] * dt).astype(np.float32)
        pos += vel * dt
        contacts = np.bincount(i, minlength=n) + np.bincount(j, minlength=n)
    total_s = time.perf_counter() - t0
    print(f"{n} grains, {args.steps} steps: {total_s:.2f} s, of which viscd {detect_s:.2f} s; "
          f"{len(pairs)} contacts at the end, pile height {pos[:, 1].max():.1f}")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from matplotlib.collections import PatchCollection
    from matplotlib.patches import Circle

    fig, ax = plt.subplots(figsize=(8, 4.5), dpi=100)
    order = np.argsort(pos[:, 2])[::-1]  # far grains first: the near ones are drawn on top
    grains = PatchCollection([Circle((pos[k, 0], pos[k, 1]), radius[k]) for k in order], cmap="viridis",
                             edgecolors="black", linewidths=0.2)
    grains.set_array(contacts[order])
    grains.set_clim(0, 8)
    sc = ax.add_collection(grains)
    ax.set_xlim(0, width)
    ax.set_ylim(0, max(10.0, float(pos[:, 1].max()) + 2))
    ax.set_aspect("equal")
    ax.set_title(f"{n} grains poured into a box, {args.steps} steps (contacts: viscd pairs)")
    fig.colorbar(sc, ax=ax, label="contacts per grain")
    fig.tight_layout()
    fig.savefig(args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
