#!/usr/bin/env python3
"""Tile an OBJ model side by side: NX x NY copies, copy (i, j) moved by (i DX, j DY, 0). Keeps the material
library and the usemtl lines of each copy; texture and normal indices are dropped (faces keep their vertices only).
A larger city from a public one, for benchmarks (docs/benchmarks.md):

    python3 scripts/tile_obj.py ../shared/models/udales_shape.obj /tmp/urb/urban3.obj 1 3 256 128
    python3 scripts/tile_obj.py ../shared/models/udales_shape.obj /tmp/urb/urban9.obj 3 3 256 128

Copy the .mtl next to OUT (the mtllib line names it as in IN).
"""
import sys


def main():
    if len(sys.argv) != 7:
        sys.exit(__doc__)
    src, out = sys.argv[1], sys.argv[2]
    nx, ny = int(sys.argv[3]), int(sys.argv[4])
    dx, dy = float(sys.argv[5]), float(sys.argv[6])
    if nx < 1 or ny < 1:
        sys.exit('NX and NY must be at least 1')
    lines = open(src).read().splitlines()
    header = [l for l in lines if l.startswith('mtllib')]
    verts = [l for l in lines if l.startswith('v ')]
    body = [l for l in lines if l.startswith('f ') or l.startswith('usemtl')]
    nv = len(verts)
    res = list(header)
    tiles = [(i, j) for i in range(nx) for j in range(ny)]
    for i, j in tiles:
        for l in verts:
            p = l.split()
            res.append('v %r %r %s' % (float(p[1]) + i * dx, float(p[2]) + j * dy, p[3]))
    for t in range(len(tiles)):
        for l in body:
            if l.startswith('usemtl'):
                res.append(l)
                continue
            idx = []
            for s in l.split()[1:]:
                k = int(s.split('/')[0])
                if k <= 0:
                    sys.exit('%s: relative (negative) vertex indices are not supported: %s' % (src, l))
                idx.append(str(k + t * nv))
            res.append('f ' + ' '.join(idx))
    with open(out, 'w') as f:
        f.write('\n'.join(res) + '\n')


if __name__ == '__main__':
    main()
