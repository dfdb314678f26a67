#!/usr/bin/env python3
"""Writes examples/storey.obj + .mtl and examples/storey.stl + storey_stl.json (python3 stdlib only).

A small storey modelled the way architects model one (issue 11): ONE floor polygon and ONE ceiling
polygon run under every room, each outer wall is one polygon running past all rooms, and the rooms
are separated by what stands on the slab:
  - a 0.2 m thick wall block [4, 4.2] x [0, 2.7] x [0, 5] (closed, outward) between room A (x < 4)
    and the east half, standing on the floor and touching the ceiling and both long walls;
  - a thin two-sided partition (one polygon, material "partition" with `two_sided 1`) at z = 2.5
    across the east half: room B (z < 2.5) and the shut storage room C (z > 2.5, no lamp);
  - a table in A whose four legs cross the floor (they run 0.1 m into the slab), and a cabinet in B
    standing on the floor.
Lamps are 0.6 m squares 5 cm under the ceiling of A and B, facing down. Without imprinting, the
floor, ceiling and long-wall patches span several rooms and light leaks into C; with it, C stays dark
(`lambert solve examples/storey.obj -o out/storey.vtu`, then the test RealModelsExample checks it).

storey.stl is the same storey as one binary STL (triangles, facet order = face order); STL has no
materials, so storey_stl.json gives them by facet range (lamps, partition two-sided).

Usage: scripts/make_storey.py [--out DIR]
"""
import argparse
import json
import os
import struct

X, Y, Z = 8.0, 2.7, 5.0
WALL = (4.0, 4.2)
PART_Z = 2.5


def quad(a, b, c, d):
    return [a, b, c, d]


def box(lo, hi):
    """Closed box, outward (faces -x, +x, -y, +y, -z, +z)."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    return [
        quad((x0, y0, z0), (x0, y0, z1), (x0, y1, z1), (x0, y1, z0)),
        quad((x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)),
        quad((x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)),
        quad((x0, y1, z0), (x0, y1, z1), (x1, y1, z1), (x1, y1, z0)),
        quad((x0, y0, z0), (x0, y1, z0), (x1, y1, z0), (x1, y0, z0)),
        quad((x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)),
    ]


def scene():
    faces = []  # (material, polygon)
    faces.append(("floor", quad((0, 0, 0), (0, 0, Z), (X, 0, Z), (X, 0, 0))))
    faces.append(("ceiling", quad((0, Y, 0), (X, Y, 0), (X, Y, Z), (0, Y, Z))))
    faces.append(("wall", quad((0, 0, 0), (0, Y, 0), (0, Y, Z), (0, 0, Z))))
    faces.append(("wall", quad((X, 0, 0), (X, 0, Z), (X, Y, Z), (X, Y, 0))))
    faces.append(("wall", quad((0, 0, 0), (X, 0, 0), (X, Y, 0), (0, Y, 0))))
    faces.append(("wall", quad((0, 0, Z), (0, Y, Z), (X, Y, Z), (X, 0, Z))))
    for f in box((WALL[0], 0, 0), (WALL[1], Y, Z)):
        faces.append(("wall", f))
    # Two-sided partition across the east half (front facing -z, into B).
    faces.append(("partition", quad((WALL[1], 0, PART_Z), (WALL[1], Y, PART_Z), (X, Y, PART_Z), (X, 0, PART_Z))))
    # Table in A: top and four legs crossing the floor.
    for f in box((1.0, 0.72, 1.5), (2.4, 0.76, 2.5)):
        faces.append(("wood", f))
    for lx, lz in ((1.05, 1.55), (2.30, 1.55), (1.05, 2.40), (2.30, 2.40)):
        for f in box((lx, -0.1, lz), (lx + 0.05, 0.72, lz + 0.05)):
            faces.append(("wood", f))
    # Cabinet in B standing on the floor.
    for f in box((6.5, 0, 0.3), (7.5, 1.8, 0.9)):
        faces.append(("wood", f))
    # Lamps (facing down) in A and B.
    for cx, cz in ((2.0, 2.5), (6.1, 1.25)):
        faces.append(("lamp", quad((cx - 0.3, Y - 0.05, cz - 0.3), (cx + 0.3, Y - 0.05, cz - 0.3),
                                   (cx + 0.3, Y - 0.05, cz + 0.3), (cx - 0.3, Y - 0.05, cz + 0.3))))
    return faces


MATERIALS = {
    "wall": {"reflectance": [0.75, 0.74, 0.70]},
    "ceiling": {"reflectance": [0.85, 0.85, 0.85]},
    "floor": {"reflectance": [0.40, 0.30, 0.20]},
    "wood": {"reflectance": [0.50, 0.35, 0.20]},
    "partition": {"reflectance": [0.60, 0.60, 0.65], "two_sided": True},
    "lamp": {"reflectance": [0.78, 0.78, 0.78], "emission": [30, 28, 24]},
}


def fmt(v):
    return "%.10g" % v


def write_obj(out, faces):
    mtl = ["# Materials of storey.obj (scripts/make_storey.py). Kd = reflectance, Ke = radiance W m^-2 sr^-1;",
           "# two_sided 1 (a lambert extension) makes each face two patches, front and back."]
    for name, m in MATERIALS.items():
        mtl.append("newmtl " + name)
        mtl.append("Kd " + " ".join(fmt(c) for c in m["reflectance"]))
        if "emission" in m:
            mtl.append("Ke " + " ".join(fmt(c) for c in m["emission"]))
        if m.get("two_sided"):
            mtl.append("two_sided 1")
    with open(os.path.join(out, "storey.mtl"), "w") as f:
        f.write("\n".join(mtl) + "\n")
    lines = ["# A storey modelled as architects do (scripts/make_storey.py): slab polygons under walls,",
             "# furniture standing on and crossing the floor, a two-sided partition. Metres, y up.",
             "mtllib storey.mtl"]
    index, verts, flines, current = {}, [], [], None
    for name, poly in faces:
        ids = []
        for p in poly:
            key = tuple(float(c) for c in p)
            if key not in index:
                index[key] = len(verts) + 1
                verts.append(key)
            ids.append(index[key])
        if name != current:
            flines.append("usemtl " + name)
            current = name
        flines.append("f " + " ".join(str(i) for i in ids))
    lines += ["v " + " ".join(fmt(c) for c in v) for v in verts] + flines
    with open(os.path.join(out, "storey.obj"), "w") as f:
        f.write("\n".join(lines) + "\n")


def write_stl(out, faces):
    tris, ranges = [], {}
    for name, poly in faces:
        first = len(tris)
        tris.append((poly[0], poly[1], poly[2]))
        tris.append((poly[0], poly[2], poly[3]))
        r = ranges.setdefault(name, [])
        if r and r[-1][1] == first - 1:
            r[-1][1] = first + 1
        else:
            r.append([first, first + 1])
    data = bytearray(b"storey (scripts/make_storey.py), binary STL".ljust(80, b" "))
    data += struct.pack("<I", len(tris))
    for t in tris:
        data += struct.pack("<3f", 0, 0, 0)
        for p in t:
            data += struct.pack("<3f", *p)
        data += b"\0\0"
    with open(os.path.join(out, "storey.stl"), "wb") as f:
        f.write(data)
    spec = {"materials": MATERIALS, "faces": []}
    for name, rs in ranges.items():
        for a, b in rs:
            spec["faces"].append({"range": [a, b], "material": name})
    with open(os.path.join(out, "storey_stl.json"), "w") as f:
        json.dump(spec, f, indent=1)
        f.write("\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "examples"))
    a = ap.parse_args()
    faces = scene()
    write_obj(a.out, faces)
    write_stl(a.out, faces)


if __name__ == "__main__":
    main()
