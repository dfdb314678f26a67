#!/usr/bin/env python3
"""Visible fraction of one pair of faces of an OBJ model, by brute force in double precision (python3 standard
library only): an independent check of a form factor's visibility, without Embree and without shaft culling.

Segments between random points of the two faces (each face fanned into triangles, uniform in area) are weighted
by the kernel cos cos / r^4 (as the solver's ray estimate) and tested against every triangle of the model whose
bounding box meets the pair's: a segment counts as blocked only if it crosses a triangle strictly inside
(barycentric coordinates > 1e-9) and strictly between its ends (1e-9 < t < 1 - 1e-9). Segments that do not leave
both faces' fronts carry no light and are skipped.

Usage:
  scripts/pair_visibility.py MODEL.obj FACE_I FACE_J [--segments N] [--seed S]

FACE_I, FACE_J: 0-based input face indices, as in `lambert formfactors` output (i,j,F_ij). Prints the number of
candidate triangles, the kernel-weighted visible fraction and the faces that blocked the most segments.
"""
import argparse
import math
import random


def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def read_obj(path):
    verts, faces = [], []
    with open(path) as f:
        for line in f:
            t = line.split()
            if not t:
                continue
            if t[0] == 'v':
                verts.append(tuple(float(x) for x in t[1:4]))
            elif t[0] == 'f':
                idx = [int(x.split('/')[0]) for x in t[1:]]
                faces.append([i - 1 if i > 0 else len(verts) + i for i in idx])
    return verts, faces


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('obj')
    ap.add_argument('i', type=int)
    ap.add_argument('j', type=int)
    ap.add_argument('--segments', type=int, default=3000)
    ap.add_argument('--seed', type=int, default=1)
    a = ap.parse_args()
    V, F = read_obj(a.obj)
    for f in (a.i, a.j):
        if not 0 <= f < len(F):
            ap.error('face %d out of range (the model has %d faces)' % (f, len(F)))

    def tris(f):
        P = [V[k] for k in F[f]]
        return [(P[0], P[k], P[k + 1]) for k in range(1, len(P) - 1)]

    def normal(f):
        P = [V[k] for k in F[f]]
        n = (0.0, 0.0, 0.0)
        for k in range(len(P)):  # Newell
            p, q = P[k], P[(k + 1) % len(P)]
            n = (n[0] + (p[1] - q[1]) * (p[2] + q[2]), n[1] + (p[2] - q[2]) * (p[0] + q[0]),
                 n[2] + (p[0] - q[0]) * (p[1] + q[1]))
        length = math.sqrt(dot(n, n))
        return tuple(x / length for x in n)

    def sampler(f):
        T = tris(f)
        area = [0.5 * math.sqrt(dot(cross(sub(b, p), sub(c, p)), cross(sub(b, p), sub(c, p)))) for p, b, c in T]
        total = sum(area)

        def sample():
            u, k = random.random() * total, 0
            while k < len(area) - 1 and u > area[k]:
                u -= area[k]
                k += 1
            p, b, c = T[k]
            s, r = math.sqrt(random.random()), random.random()
            return tuple((1 - s) * p[d] + s * (1 - r) * b[d] + s * r * c[d] for d in range(3))
        return sample

    ni, nj = normal(a.i), normal(a.j)
    pts = [V[k] for k in F[a.i] + F[a.j]]
    lo = [min(p[d] for p in pts) for d in range(3)]
    hi = [max(p[d] for p in pts) for d in range(3)]
    cand = []
    for f in range(len(F)):
        if f in (a.i, a.j):
            continue
        P = [V[k] for k in F[f]]
        if any(max(p[d] for p in P) < lo[d] or min(p[d] for p in P) > hi[d] for d in range(3)):
            continue
        cand.extend((f, t) for t in tris(f))
    print('candidate triangles', len(cand))
    random.seed(a.seed)
    si, sj = sampler(a.i), sampler(a.j)
    num = den = 0.0
    hits = {}
    for _ in range(a.segments):
        x, y = si(), sj()
        d = sub(y, x)
        cx, cy = dot(ni, d), -dot(nj, d)
        if cx <= 0 or cy <= 0:
            continue
        r2 = dot(d, d)
        w = cx * cy / (r2 * r2)
        den += w
        hit = None
        for f, (p, b, c) in cand:
            e1, e2 = sub(b, p), sub(c, p)
            q = cross(d, e2)
            det = dot(e1, q)
            if det == 0:
                continue
            tv = sub(x, p)
            u = dot(tv, q) / det
            if u < 1e-9 or u > 1 - 1e-9:
                continue
            r = cross(tv, e1)
            v = dot(d, r) / det
            if v < 1e-9 or u + v > 1 - 1e-9:
                continue
            if 1e-9 < dot(e2, r) / det < 1 - 1e-9:
                hit = f
                break
        if hit is None:
            num += w
        else:
            hits[hit] = hits.get(hit, 0) + 1
    if den == 0:
        print('no segment leaves both fronts: the faces exchange nothing')
        return
    print('visible fraction %.6f' % (num / den))
    print('blocking faces (segments):', sorted(hits.items(), key=lambda h: -h[1])[:5])


if __name__ == '__main__':
    main()
