#!/usr/bin/env python3
"""Turn an OBJ model about its vertical axis and optionally round its corners to single precision, as a model placed in
GIS coordinates and exported as a binary STL would be: for checking that lambert's results do not depend on how a
model is turned or stored (docs/benchmarks.md, thirty-second session).

Only `v` lines change (the first three coordinates); `mtllib` is made absolute so the output can live elsewhere; every
other line (faces with relative or absolute indices, materials, groups) is copied as it is.

Usage: python3 scripts/turn_model.py IN.obj OUT.obj [--degrees 30] [--up y|z] [--single]
"""
import argparse
import math
import os
import struct


def to_single(x):
    return struct.unpack("f", struct.pack("f", x))[0]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("src")
    ap.add_argument("out")
    ap.add_argument("--degrees", type=float, default=30.0, help="turn about the vertical axis (default 30)")
    ap.add_argument("--up", choices=("y", "z"), default="y", help="the vertical axis (default y)")
    ap.add_argument("--single", action="store_true", help="round every coordinate to single precision")
    a = ap.parse_args()
    c, s = math.cos(math.radians(a.degrees)), math.sin(math.radians(a.degrees))
    folder = os.path.dirname(os.path.realpath(a.src))
    out = []
    with open(a.src) as f:
        for line in f:
            t = line.split()
            if t and t[0] == "v":
                x, y, z = map(float, t[1:4])
                if a.up == "y":
                    p = (c * x - s * z, y, s * x + c * z)
                else:
                    p = (c * x - s * y, s * x + c * y, z)
                if a.single:
                    p = tuple(to_single(v) for v in p)
                out.append("v %.17g %.17g %.17g\n" % p)
            elif t and t[0] == "mtllib":
                out.append("mtllib " + os.path.join(folder, t[1]) + "\n")
            else:
                out.append(line)
    with open(a.out, "w") as f:
        f.writelines(out)


if __name__ == "__main__":
    main()
