#!/usr/bin/env python3
"""A small generated city for orientation checks: a 100 m x 100 m ground of 10 x 10 quads facing up and 16 box
buildings (random sizes, fixed seed) standing on it without bottom faces, wound outward, as urban models come.

    python3 scripts/make_city.py OUT.obj [--split-walls]

--split-walls splits every wall in two along its height. Writes OUT.obj and city.mtl beside it (one grey
material, rho = 0.3). Mirror it with scripts/mirror_obj.py to get the same city inside out.
"""
import os
import random
import sys


def main():
    args = [a for a in sys.argv[1:] if not a.startswith('--')]
    split = '--split-walls' in sys.argv[1:]
    if len(args) != 1:
        sys.exit(__doc__)
    out = args[0]
    rng = random.Random(3)
    V, F = [], []

    def v(p):
        V.append(p)
        return len(V)

    n, size = 10, 10.0
    grid = {(i, j): v((i * size, 0.0, j * size)) for i in range(n + 1) for j in range(n + 1)}
    for i in range(n):
        for j in range(n):
            F.append([grid[i, j], grid[i, j + 1], grid[i + 1, j + 1], grid[i + 1, j]])  # facing +y

    def building(x0, z0, w, d, h):
        xs, zs = (x0, x0 + w), (z0, z0 + d)
        corner = {(a, b, k): v((xs[a], (0.0, h)[k], zs[b])) for a in range(2) for b in range(2) for k in range(2)}
        for a, b in (((0, 0), (1, 0)), ((1, 0), (1, 1)), ((1, 1), (0, 1)), ((0, 1), (0, 0))):  # facing out
            if split:
                mid_a, mid_b = v((xs[a[0]], h / 2, zs[a[1]])), v((xs[b[0]], h / 2, zs[b[1]]))
                F.append([corner[a + (0,)], mid_a, mid_b, corner[b + (0,)]])
                F.append([mid_a, corner[a + (1,)], corner[b + (1,)], mid_b])
            else:
                F.append([corner[a + (0,)], corner[a + (1,)], corner[b + (1,)], corner[b + (0,)]])
        F.append([corner[0, 0, 1], corner[0, 1, 1], corner[1, 1, 1], corner[1, 0, 1]])  # roof, facing +y

    for bx in range(4):
        for bz in range(4):
            building(8 + bx * 23 + rng.uniform(0, 3), 8 + bz * 23 + rng.uniform(0, 3), rng.uniform(8, 12),
                     rng.uniform(8, 12), rng.uniform(6, 30))
    with open(os.path.join(os.path.dirname(os.path.abspath(out)), 'city.mtl'), 'w') as f:
        f.write('newmtl grey\nKd 0.3 0.3 0.3\n')
    with open(out, 'w') as f:
        f.write('# scripts/make_city.py%s\nmtllib city.mtl\nusemtl grey\n' % (' --split-walls' if split else ''))
        f.writelines('v %r %r %r\n' % p for p in V)
        f.writelines('f ' + ' '.join(map(str, q)) + '\n' for q in F)


if __name__ == '__main__':
    main()
