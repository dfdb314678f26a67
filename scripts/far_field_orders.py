#!/usr/bin/env python3
"""How the hierarchy's far-field expansion errs, by its order (an estimate for issue 13's lit cube).

The hierarchical operator (formfactor/src/hierarchy_apply.cpp) expands the point kernel
    n_i . K(u) n_j A_j,   K(u) = -u u^T / (pi |u|^4),   u = c_B + b - (c_A + a)
in the offsets b (source points from the source cluster's centre) and a (receiver points from the receiver
cluster's centre) to total order 3 (2 until the thirty-first session, which this script's estimate led to change:
docs/benchmarks.md). This script sums the kernel over small clusters of points (patch centroids of
a 1/64 grid, as in the 64-cube) directly, and against the Taylor expansion cut at total order 2, 3 and 4, and prints
the largest and the mean error relative to each receiver's exact sum. The third-order terms are odd in the offsets:
they cancel on a cluster's average but not at a receiver near its edge, and in grazing configurations they dominate.

Needs python3-sympy (Debian), which the project itself does not use. Takes a few seconds.
Usage: python3 scripts/far_field_orders.py
"""
import itertools
import math
from math import factorial

import sympy as sp

u = sp.symbols("u0:3")
w = sp.symbols("w0:3")
r2 = sum(ui * ui for ui in u)
F = [-u[i] * sum(u[k] * w[k] for k in range(3)) / (sp.pi * r2**2) for i in range(3)]  # K(u) w
_cache = {}


def D(idx, U, W):
    """The derivative of K(u) w along the axes in idx, at u = U."""
    key = tuple(sorted(idx))
    if key not in _cache:
        expr = [sp.diff(F[i], *[u[k] for k in key]) if key else F[i] for i in range(3)]
        _cache[key] = sp.lambdify(list(u) + list(w), expr, "math")
    return _cache[key](*U, *W)


def taylor(U, a, b, v, order):
    """sum over m + n <= order of (b . grad)^m (-a . grad)^n K(U) v / (m! n!)."""
    tot = [0.0, 0.0, 0.0]
    for m in range(order + 1):
        for n in range(order + 1 - m):
            c = (-1) ** n / (factorial(m) * factorial(n))
            for ib in itertools.product(range(3), repeat=m):
                pb = math.prod(b[k] for k in ib)
                if pb == 0:
                    continue
                for ia in itertools.product(range(3), repeat=n):
                    pa = math.prod(a[k] for k in ia)
                    if pa == 0:
                        continue
                    d = D(ib + ia, U, v)
                    for i in range(3):
                        tot[i] += c * pb * pa * d[i]
    return tot


def grid(c, e1, e2, n, h):
    return [[c[k] + (i - (n - 1) / 2) * h * e1[k] + (j - (n - 1) / 2) * h * e2[k] for k in range(3)]
            for i in range(n) for j in range(n)]


def run(name, A, nA, B, nB, area, orders=(2, 3, 4)):
    cA = [sum(p[k] for p in A) / len(A) for k in range(3)]
    cB = [sum(p[k] for p in B) / len(B) for k in range(3)]
    U = [cB[k] - cA[k] for k in range(3)]
    v = [area * nB[k] for k in range(3)]
    s = (max(math.dist(p, cA) for p in A) + max(math.dist(q, cB) for q in B)) / math.hypot(*U)
    err = {o: [] for o in orders}
    vals = []
    for p in A[::3]:
        a = [p[k] - cA[k] for k in range(3)]
        exact = 0.0
        tot = {o: 0.0 for o in orders}
        for q in B:
            b = [q[k] - cB[k] for k in range(3)]
            exact += sum(nA[i] * x for i, x in enumerate(D((), [U[k] + b[k] - a[k] for k in range(3)], v)))
            for o in orders:
                tot[o] += sum(nA[i] * x for i, x in enumerate(taylor(U, a, b, v, o)))
        vals.append(exact)
        for o in orders:
            err[o].append(tot[o] - exact)
    print(f"{name} (s = {s:.3f}):")
    for o in orders:
        print(f"  order {o}: max relative error {max(abs(e / x) for e, x in zip(err[o], vals)):.2e}, "
              f"mean {sum(err[o]) / sum(vals):+.2e}")


if __name__ == "__main__":
    h = 1 / 64
    run("facing walls, 4 x 4 receivers, 8 x 8 sources, 0.6 apart",
        grid([1, 0.5, 0.5], [0, 1, 0], [0, 0, 1], 4, h), [-1, 0, 0],
        grid([0.4, 0.45, 0.55], [0, 1, 0], [0, 0, 1], 8, h), [1, 0, 0], h * h)
    run("wall top lit by a ceiling cluster at grazing incidence",
        grid([1, 0.48, 0.97], [0, 1, 0], [0, 0, 1], 4, h), [-1, 0, 0],
        grid([0.2, 0.65, 1.0], [1, 0, 0], [0, 1, 0], 6, h), [0, 0, -1], h * h)
