#!/usr/bin/env python3
"""A closed unit cube of triangles whose interior vertices are jittered along their face's normal: a stand-in for a
scanned (rough) surface, for measuring how visibility copes with bumps (docs/benchmarks.md, thirty-first session).

Each face is N x N quads split into two triangles, faces inward, reflectance 0.5; the top face (+z) emits Le = 1.
Vertices on the cube's edges stay put (the surface stays closed); the others move by a uniform random offset in
[-J, J] metres along the face's normal.

Usage: python3 scripts/make_rough_cube.py [--n N] [--jitter J] [--seed S] --out DIR   (writes DIR/rough_cube.obj)
"""
import argparse
import os
import random


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=32, help="quads per face edge (default 32: 12,288 triangles)")
    ap.add_argument("--jitter", type=float, default=0.002, help="largest offset along the normal, m (default 0.002)")
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--out", required=True, help="output directory")
    a = ap.parse_args()
    rng = random.Random(a.seed)
    n = a.n
    index, points, faces = {}, [], []

    def vertex(p):
        key = tuple(round(c * n) for c in p)
        if key not in index:
            q = list(p)
            on = [c == 0 or c == 1 for c in p]
            if sum(on) == 1:  # inside one face: move along its normal
                q[on.index(True)] += rng.uniform(-a.jitter, a.jitter)
            index[key] = len(points) + 1
            points.append(q)
        return index[key]

    for ax in range(3):
        u, v = [k for k in range(3) if k != ax]
        for side in (0, 1):
            # (u, v, ax) is right-handed when v follows u cyclically; inward means the normal points to the inside.
            flip = ((u - ax) % 3 == 1) != (side == 0)
            material = "light" if (ax == 2 and side == 1) else "wall"
            for i in range(n):
                for j in range(n):
                    def corner(di, dj):
                        p = [0.0, 0.0, 0.0]
                        p[ax], p[u], p[v] = side, (i + di) / n, (j + dj) / n
                        return vertex(p)
                    q = [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)]
                    for t in ((q[0], q[1], q[2]), (q[0], q[2], q[3])):
                        faces.append(((t[0], t[2], t[1]) if flip else t, material))
    os.makedirs(a.out, exist_ok=True)
    with open(os.path.join(a.out, "rough_cube.mtl"), "w") as f:
        f.write("newmtl wall\nKd 0.5 0.5 0.5\nnewmtl light\nKd 0.5 0.5 0.5\nKe 1 1 1\n")
    with open(os.path.join(a.out, "rough_cube.obj"), "w") as f:
        f.write("mtllib rough_cube.mtl\n")
        for p in points:
            f.write("v %.9f %.9f %.9f\n" % tuple(p))
        current = None
        for t, m in faces:
            if m != current:
                f.write(f"usemtl {m}\n")
                current = m
            f.write("f %d %d %d\n" % t)
    print(f"{len(points)} vertices, {len(faces)} triangles -> {a.out}/rough_cube.obj")


if __name__ == "__main__":
    main()
