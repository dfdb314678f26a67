#!/usr/bin/env python3
"""Writes the example scenes in examples/ (python3 standard library only).

  cornell_box.obj + .mtl   the Cornell box from its published coordinates (mm -> m), as published
  cornell_box_fine.obj     the same faces, each split bilinearly into N x N quads (uses cornell_box.mtl)
  room.obj + room.mtl      a furnished 5 m x 4 m x 2.7 m room with a ceiling light and a window

Units: metres. y is up in every scene. MTL Kd = diffuse reflectance, Ke = emitted radiance
(W m^-2 sr^-1) per channel. Every face's front (right-hand-rule normal) is checked here: room and box
surfaces face the interior, furniture and blocks face outward.

Usage: scripts/make_examples.py [--out DIR] [--fine N]
"""
import argparse
import math
import os

# ---------------------------------------------------------------------------------------------------
# Geometry helpers


def sub(a, b):
    return tuple(x - y for x, y in zip(a, b))


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def newell(poly):
    """Newell normal: right-hand rule on the corner order, length = 2 * area for planar polygons."""
    n = [0.0, 0.0, 0.0]
    for i, p in enumerate(poly):
        q = poly[(i + 1) % len(poly)]
        n[0] += (p[1] - q[1]) * (p[2] + q[2])
        n[1] += (p[2] - q[2]) * (p[0] + q[0])
        n[2] += (p[0] - q[0]) * (p[1] + q[1])
    return tuple(n)


def centroid(points):
    return tuple(sum(p[i] for p in points) / len(points) for i in range(3))


def lerp(a, b, t):
    return tuple(x + (y - x) * t for x, y in zip(a, b))


def nonplanarity(poly):
    """Largest distance of a corner from the plane through the centroid with the Newell normal."""
    n = newell(poly)
    length = math.sqrt(dot(n, n))
    c = centroid(poly)
    return max(abs(dot(sub(p, c), n)) / length for p in poly)


class ObjWriter:
    """Collects named objects of polygons; vertices are shared between faces (exact coordinates)."""

    def __init__(self):
        self.vertices = []
        self.index = {}
        self.objects = []  # (name, material, [[vertex index...]...])

    def vertex(self, p):
        key = tuple(round(x, 9) for x in p)
        if key not in self.index:
            self.index[key] = len(self.vertices)
            self.vertices.append(key)
        return self.index[key]

    def add(self, name, material, polygons):
        self.objects.append((name, material, [[self.vertex(p) for p in poly] for poly in polygons]))

    def write(self, path, header, mtllib):
        with open(path, "w") as f:
            for line in header:
                f.write("# " + line + "\n" if line else "#\n")
            f.write("mtllib %s\n\n" % mtllib)
            for v in self.vertices:
                f.write("v %s\n" % " ".join(fmt(x) for x in v))
            for name, material, faces in self.objects:
                f.write("\no %s\nusemtl %s\n" % (name, material))
                for face in faces:
                    f.write("f %s\n" % " ".join(str(i + 1) for i in face))
        faces = sum(len(o[2]) for o in self.objects)
        print("wrote %s: %d vertices, %d faces" % (path, len(self.vertices), faces))


def fmt(x):
    s = "%.9f" % x
    s = s.rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def write_mtl(path, header, materials):
    """materials: [(name, Kd (r,g,b), Ke (r,g,b) or None, comment)]"""
    with open(path, "w") as f:
        for line in header:
            f.write("# " + line + "\n" if line else "#\n")
        for name, kd, ke, comment in materials:
            f.write("\n")
            for line in comment:
                f.write("# %s\n" % line)
            f.write("newmtl %s\n" % name)
            f.write("Kd %s\n" % " ".join(fmt(x) for x in kd))
            if ke is not None:
                f.write("Ke %s\n" % " ".join(fmt(x) for x in ke))
    print("wrote %s: %d materials" % (path, len(materials)))


def check_facing(polygons, point, inward, what):
    """inward: every front faces `point` (room interior); else every front faces away (solid)."""
    for poly in polygons:
        d = dot(newell(poly), sub(point, centroid(poly)))
        if (d <= 0) if inward else (d >= 0):
            raise SystemExit("%s: face %s faces the wrong way" % (what, poly))


# ---------------------------------------------------------------------------------------------------
# Cornell box: Cornell University Program of Computer Graphics, "Cornell Box Data",
# http://www.graphics.cornell.edu/online/box/data.html (millimetres, camera at (278, 273, -800)
# looking along +z, y up). Corner lists exactly as published, in published order.

CORNELL_MM = {
    "floor": [[(552.8, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 559.2), (549.6, 0.0, 559.2)]],
    # Published in the ceiling plane y = 548.8; lowered by 0.1 mm (y = 548.7) so the emitter does
    # not coincide with the ceiling (as in the widely used renderings of this data).
    "light": [[(343.0, 548.7, 227.0), (343.0, 548.7, 332.0), (213.0, 548.7, 332.0), (213.0, 548.7, 227.0)]],
    "ceiling": [[(556.0, 548.8, 0.0), (556.0, 548.8, 559.2), (0.0, 548.8, 559.2), (0.0, 548.8, 0.0)]],
    "back_wall": [[(549.6, 0.0, 559.2), (0.0, 0.0, 559.2), (0.0, 548.8, 559.2), (556.0, 548.8, 559.2)]],
    "right_wall": [[(0.0, 0.0, 559.2), (0.0, 0.0, 0.0), (0.0, 548.8, 0.0), (0.0, 548.8, 559.2)]],
    "left_wall": [[(552.8, 0.0, 0.0), (549.6, 0.0, 559.2), (556.0, 548.8, 559.2), (556.0, 548.8, 0.0)]],
    "short_block": [
        [(130.0, 165.0, 65.0), (82.0, 165.0, 225.0), (240.0, 165.0, 272.0), (290.0, 165.0, 114.0)],
        [(290.0, 0.0, 114.0), (290.0, 165.0, 114.0), (240.0, 165.0, 272.0), (240.0, 0.0, 272.0)],
        [(130.0, 0.0, 65.0), (130.0, 165.0, 65.0), (290.0, 165.0, 114.0), (290.0, 0.0, 114.0)],
        [(82.0, 0.0, 225.0), (82.0, 165.0, 225.0), (130.0, 165.0, 65.0), (130.0, 0.0, 65.0)],
        [(240.0, 0.0, 272.0), (240.0, 165.0, 272.0), (82.0, 165.0, 225.0), (82.0, 0.0, 225.0)],
    ],
    "tall_block": [
        [(423.0, 330.0, 247.0), (265.0, 330.0, 296.0), (314.0, 330.0, 456.0), (472.0, 330.0, 406.0)],
        [(423.0, 0.0, 247.0), (423.0, 330.0, 247.0), (472.0, 330.0, 406.0), (472.0, 0.0, 406.0)],
        [(472.0, 0.0, 406.0), (472.0, 330.0, 406.0), (314.0, 330.0, 456.0), (314.0, 0.0, 456.0)],
        [(314.0, 0.0, 456.0), (314.0, 330.0, 456.0), (265.0, 330.0, 296.0), (265.0, 0.0, 296.0)],
        [(265.0, 0.0, 296.0), (265.0, 330.0, 296.0), (423.0, 330.0, 247.0), (423.0, 0.0, 247.0)],
    ],
}
CORNELL_MATERIAL = {"floor": "white", "light": "light", "ceiling": "white", "back_wall": "white",
                    "right_wall": "green", "left_wall": "red", "short_block": "white", "tall_block": "white"}

# Light: 130 mm x 105 mm = 0.01365 m^2. Ke = 10 x (17, 12, 4), the RGB radiance of the light in common
# renderings of this box, gives a radiant power pi * A * Ke = (7.3, 5.1, 1.7) W (14 W in all: about the
# visible output of a 100 W incandescent bulb), roughly 8 W m^-2 per channel on the floor below it.
CORNELL_LIGHT_KE = (170.0, 120.0, 40.0)


def cornell_polygons(fine):
    """{name: [polygon in metres]}; fine > 1 splits each quad bilinearly into fine x fine quads."""
    out = {}
    for name, quads in CORNELL_MM.items():
        polys = []
        for quad in quads:
            q = [tuple(x / 1000.0 for x in p) for p in quad]
            if fine <= 1:
                polys.append(q)
                continue
            # Bilinear split: corners q0 q1 q2 q3; shared edges of neighbouring faces get the same points.
            def at(s, t):
                return lerp(lerp(q[0], q[1], s), lerp(q[3], q[2], s), t)
            for i in range(fine):
                for j in range(fine):
                    s0, s1, t0, t1 = i / fine, (i + 1) / fine, j / fine, (j + 1) / fine
                    polys.append([at(s0, t0), at(s1, t0), at(s1, t1), at(s0, t1)])
        out[name] = polys
    return out


def make_cornell(outdir, fine):
    interior = (0.278, 0.274, 0.280)
    header = [
        "Cornell box, from the Cornell University Program of Computer Graphics \"Cornell Box Data\"",
        "(http://www.graphics.cornell.edu/online/box/data.html), converted from millimetres to metres.",
        "Generated by scripts/make_examples.py; y is up, the open side faces -z (camera at (0.278, 0.273, -0.8)).",
        "Corner lists and their order are as published: walls, floor, ceiling and light face the interior,",
        "block faces face outward (right-hand rule). Blocks have no bottom face (they stand on the floor).",
        "Changed: the light is 0.1 mm below the ceiling (published: in the ceiling plane y = 548.8 mm).",
        "Kept as published: the red left wall (x = 549.6 .. 556 mm) is not planar (a corner lies ~%.1f mm off"
        % (1000 * nonplanarity([tuple(x / 1000.0 for x in p) for p in CORNELL_MM["left_wall"][0]])),
        "its best plane); lambert triangulates it and reports it.",
    ]
    variants = [("cornell_box.obj", 1)]
    if fine > 1:
        variants.append(("cornell_box_fine.obj", fine))
    for filename, n in variants:
        w = ObjWriter()
        polys = cornell_polygons(n)
        for name in ["floor", "ceiling", "light", "back_wall", "right_wall", "left_wall", "short_block", "tall_block"]:
            if name.endswith("block"):
                check_facing(polys[name], centroid([p for poly in polys[name] for p in poly]), False, name)
            else:
                check_facing(polys[name], interior, True, name)
            w.add(name, CORNELL_MATERIAL[name], polys[name])
        extra = [] if n == 1 else ["This variant splits every published quad into %d x %d quads (bilinear)." % (n, n)]
        w.write(os.path.join(outdir, filename), header + extra, "cornell_box.mtl")
    write_mtl(os.path.join(outdir, "cornell_box.mtl"), [
        "Cornell box materials (RGB approximations of the published reflectance spectra).",
        "Kd = diffuse reflectance, Ke = emitted radiance in W m^-2 sr^-1.",
    ], [
        ("white", (0.73, 0.73, 0.73), None, []),
        ("red", (0.63, 0.065, 0.05), None, []),
        ("green", (0.14, 0.45, 0.091), None, []),
        ("light", (0.78, 0.78, 0.78), CORNELL_LIGHT_KE, [
            "Light 0.130 m x 0.105 m = 0.01365 m^2. Ke = 10 x (17, 12, 4) (the usual RGB radiance of this",
            "light in renderings) -> radiant power pi * A * Ke = (7.3, 5.1, 1.7) W, 14 W in all (each channel",
            "about a third of the visible band): the visible output of a ~100 W incandescent bulb.",
            "That gives ~8 W m^-2 per channel on the floor below the light.",
        ]),
    ])


# ---------------------------------------------------------------------------------------------------
# Furnished room: 5 m (x) x 4 m (z) x 2.7 m (y, up).

ROOM = (5.0, 2.7, 4.0)
WINDOW = {"z": (1.2, 2.8), "y": (0.9, 2.2)}   # in the wall x = 0
LAMP = {"x": (1.9, 3.1), "z": (1.7, 2.3)}     # recessed in the ceiling, 1.2 m x 0.6 m
WALL_CELL = 0.5                                # largest room-surface quad edge (m)
FURNITURE_CELL = 0.25                          # largest furniture quad edge (m)


def breaks(lo, hi, cuts, cell):
    """Sorted grid coordinates from lo to hi through every cut, no interval longer than cell."""
    pts = sorted(set([lo, hi] + [c for c in cuts if lo < c < hi]))
    out = [lo]
    for a, b in zip(pts, pts[1:]):
        n = max(1, math.ceil((b - a) / cell - 1e-9))
        out += [a + (b - a) * k / n for k in range(1, n + 1)]
    return out


def oriented(poly, normal):
    return poly if dot(newell(poly), normal) > 0 else poly[::-1]


def rect_grid(axis, value, u_axis, us, v_axis, vs, normal, keep=lambda u0, u1, v0, v1: True):
    """Quads of the plane coordinate[axis] = value over the grid us x vs, fronts along normal."""
    polys = []
    for u0, u1 in zip(us, us[1:]):
        for v0, v1 in zip(vs, vs[1:]):
            if not keep(u0, u1, v0, v1):
                continue
            corners = []
            for u, v in [(u0, v0), (u1, v0), (u1, v1), (u0, v1)]:
                p = [0.0, 0.0, 0.0]
                p[axis], p[u_axis], p[v_axis] = value, u, v
                corners.append(tuple(p))
            polys.append(oriented(corners, normal))
    return polys


def inside(lo_hi_u, lo_hi_v):
    (ua, ub), (va, vb) = lo_hi_u, lo_hi_v
    return lambda u0, u1, v0, v1: ua <= u0 and u1 <= ub and va <= v0 and v1 <= vb


def box_faces(lo, hi, faces, cell):
    """Outward quads of the box [lo, hi]; faces: subset of '-x +x -y +y -z +z' (omit hidden ones)."""
    polys = []
    grids = [breaks(lo[a], hi[a], [], cell) for a in range(3)]
    for f in faces.split():
        axis = "xyz".index(f[1])
        sign = 1.0 if f[0] == "+" else -1.0
        u_axis, v_axis = [a for a in range(3) if a != axis]
        normal = [0.0, 0.0, 0.0]
        normal[axis] = sign
        value = hi[axis] if sign > 0 else lo[axis]
        polys += rect_grid(axis, value, u_axis, grids[u_axis], v_axis, grids[v_axis], normal)
    return polys


def make_room(outdir):
    X, Y, Z = ROOM
    # One set of grid lines per axis for all room surfaces: neighbouring walls share their edge vertices.
    xs = breaks(0.0, X, list(LAMP["x"]), WALL_CELL)
    ys = breaks(0.0, Y, list(WINDOW["y"]), WALL_CELL)
    zs = breaks(0.0, Z, list(WINDOW["z"]) + list(LAMP["z"]), WALL_CELL)
    not_window = lambda u0, u1, v0, v1: not inside((WINDOW["y"]), (WINDOW["z"]))(u0, u1, v0, v1)
    not_lamp = lambda u0, u1, v0, v1: not inside((LAMP["x"]), (LAMP["z"]))(u0, u1, v0, v1)
    room = [
        ("floor", "oak_floor", rect_grid(1, 0.0, 0, xs, 2, zs, (0, 1, 0))),
        ("ceiling", "ceiling_white", rect_grid(1, Y, 0, xs, 2, zs, (0, -1, 0), not_lamp)),
        ("ceiling_light", "led_panel", rect_grid(1, Y, 0, xs, 2, zs, (0, -1, 0), inside(LAMP["x"], LAMP["z"]))),
        ("wall_west", "wall_paint", rect_grid(0, 0.0, 1, ys, 2, zs, (1, 0, 0), not_window)),
        ("window", "window_daylight", rect_grid(0, 0.0, 1, ys, 2, zs, (1, 0, 0), inside(WINDOW["y"], WINDOW["z"]))),
        ("wall_east", "wall_paint", rect_grid(0, X, 1, ys, 2, zs, (-1, 0, 0))),
        ("wall_north", "wall_paint", rect_grid(2, 0.0, 0, xs, 1, ys, (0, 0, 1))),
        ("wall_south", "wall_paint", rect_grid(2, Z, 0, xs, 1, ys, (0, 0, -1))),
    ]
    # Furniture: faces resting on the floor or against the table top are left out (they would receive
    # no light and touch another surface); every other box face faces outward.
    top_lo, top_hi = (1.2, 0.72, 2.4), (2.6, 0.76, 3.3)  # table top 1.4 m x 0.9 m, 4 cm thick
    legs = []
    for x in (top_lo[0] + 0.05, top_hi[0] - 0.10):
        for z in (top_lo[2] + 0.05, top_hi[2] - 0.10):
            legs.append(((x, 0.0, z), (x + 0.05, top_lo[1], z + 0.05)))
    furniture = [
        ("table_top", "table_wood", (top_lo, top_hi), "-x +x -y +y -z +z"),
        ("bed", "bed_fabric", ((3.55, 0.0, 0.05), (4.95, 0.5, 2.05)), "-x +x +y -z +z"),
        ("cupboard", "cupboard_paint", ((0.3, 0.0, 3.4), (1.5, 2.0, 3.95)), "-x +x +y -z +z"),
    ] + [("table_leg_%d" % (i + 1), "table_wood", leg, "-x +x -z +z") for i, leg in enumerate(legs)]

    centre = (X / 2, Y / 2, Z / 2)
    w = ObjWriter()
    for name, material, polys in room:
        check_facing(polys, centre, True, name)
        w.add(name, material, polys)
    for name, material, (lo, hi), faces in furniture:
        polys = box_faces(lo, hi, faces, FURNITURE_CELL)
        check_facing(polys, centroid([lo, hi]), False, name)
        w.add(name, material, polys)
    w.write(os.path.join(outdir, "room.obj"), [
        "Furnished room, 5 m (x) x 4 m (z) x 2.7 m (y, up), metres. Generated by scripts/make_examples.py.",
        "Room surfaces face the interior and share one grid (quads <= %.2f m) so neighbours share vertices;" % WALL_CELL,
        "the window (wall x = 0) and the recessed ceiling light fill holes in that grid.",
        "Furniture boxes (quads <= %.2f m) face outward; faces resting on the floor or under the table top" % FURNITURE_CELL,
        "are omitted.",
    ], "room.mtl")
    lamp_area = (LAMP["x"][1] - LAMP["x"][0]) * (LAMP["z"][1] - LAMP["z"][0])
    window_area = (WINDOW["y"][1] - WINDOW["y"][0]) * (WINDOW["z"][1] - WINDOW["z"][0])
    lamp_ke, window_ke = (2.1, 2.0, 1.8), (6.0, 6.6, 7.4)
    write_mtl(os.path.join(outdir, "room.mtl"), [
        "Room materials. Kd = diffuse reflectance, Ke = emitted radiance in W m^-2 sr^-1.",
        "Each channel carries about a third of the visible band: R + G + B = visible radiance.",
    ], [
        ("wall_paint", (0.80, 0.79, 0.75), None, ["off-white matt paint"]),
        ("ceiling_white", (0.85, 0.85, 0.85), None, []),
        ("oak_floor", (0.45, 0.32, 0.20), None, []),
        ("table_wood", (0.55, 0.38, 0.22), None, []),
        ("bed_fabric", (0.20, 0.28, 0.50), None, ["blue cover"]),
        ("cupboard_paint", (0.70, 0.66, 0.58), None, []),
        ("led_panel", (0.80, 0.80, 0.80), lamp_ke, [
            "%.2f m^2 LED panel, ~4000 lm (~13 W visible at ~300 lm/W): luminance ~1800 cd m^-2," % lamp_area,
            "radiance ~5.9 W m^-2 sr^-1 in all, warm white. Power pi * A * Ke = (%.1f, %.1f, %.1f) W."
            % tuple(math.pi * lamp_area * k for k in lamp_ke),
        ]),
        ("window_daylight", (0.08, 0.08, 0.08), window_ke, [
            "%.2f m^2 window showing a uniform overcast sky of ~5000 cd m^-2 (~20 W m^-2 sr^-1 at ~250 lm/W)," % window_area,
            "bluish. Kd 0.08: the little light glass reflects back. Power pi * A * Ke = (%.0f, %.0f, %.0f) W."
            % tuple(math.pi * window_area * k for k in window_ke),
        ]),
    ])


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default=os.path.join(here, os.pardir, "examples"), help="output directory")
    parser.add_argument("--fine", type=int, default=8, help="quads per edge in cornell_box_fine.obj (<= 1: none)")
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)
    make_cornell(args.out, args.fine)
    make_room(args.out)


if __name__ == "__main__":
    main()
