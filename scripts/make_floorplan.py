#!/usr/bin/env python3
"""Writes examples/floorplan.obj + floorplan.mtl: a furnished floor of five rooms (python3 standard library only).

Plan (metres, x east, z south, y up; interior faces of the walls, ceiling height 2.7 m):

    z=0   +-----------------------+----------------+
          | living                | kitchen        |   windows (daylight) in the exterior walls
          | 5.95 x 4.95           D 3.95 x 3.95    |   D = door opening (0.9 m x 2.1 m)
          |                       +----------------+
          +----------D------------| storage (shut) |   the storage room has no door, no window and
          | bedroom               | 3.95 x 1.9     |   no light: it shares walls with all four
          | 5.95 x 3.95           +----------------+   lit rooms and must stay dark
          |                       D study          |
    z=9   +-----------------------+----------------+
          x=0                    x=6              x=10

Interior walls are 0.1 m thick: each room is its own closed box of inward-facing surfaces (floor,
ceiling, four walls), so a wall between two rooms is two faces 0.1 m apart, and light passes from one
room to the next only through door openings. A door opening is cut through both faces and lined with
reveal faces (two jambs, head and threshold) facing into the opening. Windows are 0.15 m deep openings
in the exterior walls (sill, head, jambs) closed by an emitting rectangle: an overcast sky seen through
glass. Each lit room has a ceiling light: an emitting rectangle 2 cm below the ceiling, facing down.
Furniture is made of boxes with outward faces; box faces that touch the floor, a wall or another box
are left out.

Meshing leaves on purpose what real architectural models contain:
  * coplanar adjacent faces: every floor is several rectangles (a rug, boards, tiles), each meshed on
    its own grid;
  * T-junctions: floors, walls and ceilings are meshed independently (quads <= 0.5 m; walls are split
    at their door and window edges, floors and ceilings are not), so a wall's bottom vertices do not
    match the floor's, and reveal, wall-corner and furniture-contact edges end on other faces' edges.

Conventions as in examples/README.md: MTL Kd = diffuse reflectance, Ke = emitted radiance
W m^-2 sr^-1; a face's front is the right-hand-rule normal; one-sided surfaces. Group names
(`o`) are ROOM/OBJECT (doors: door/ROOM-ROOM).

Usage:
  scripts/make_floorplan.py [--out DIR]           write floorplan.obj + floorplan.mtl
  scripts/make_floorplan.py --building FACES [--storeys S] [--out DIR]
                                                  write building.obj + .mtl: storeys x wings of the plan,
                                                  about FACES faces (scaling benchmarks)
  scripts/make_floorplan.py --check SOLUTION.vtu [--obj OBJ]
                                                  per-room radiance of a `lambert solve` result (exit 1 if
                                                  the shut room is lit or a lit room dark); for a building
                                                  (--obj building.obj) the rooms of every copy together
"""
import argparse
import math
import os
import struct
import sys
import xml.etree.ElementTree as ET
import zlib

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from make_examples import (ObjWriter, breaks, centroid, check_facing, dot, newell,  # noqa: E402
                           oriented, write_mtl)

H = 2.7              # ceiling height
WALL = 0.5           # largest quad edge on floors, walls, ceilings (m)
FURN = 0.25          # largest quad edge on furniture and reveals (m)
WINDOW_DEPTH = 0.15  # glass plane behind the interior face of an exterior wall
LIGHT_DROP = 0.02    # ceiling lights hang this far below the ceiling

# Interior rectangles (x range, z range) of each room.
ROOMS = {
    "living":  ((0.0, 5.95), (0.0, 4.95)),
    "kitchen": ((6.05, 10.0), (0.0, 3.95)),
    "storage": ((6.05, 10.0), (4.05, 5.95)),
    "bedroom": ((0.0, 5.95), (5.05, 9.0)),
    "study":   ((6.05, 10.0), (6.05, 9.0)),
}
CLOSED_ROOM = "storage"

WALL_MATERIAL = {"living": "wall_paint", "kitchen": "wall_green", "bedroom": "wall_blue",
                 "study": "wall_yellow", "storage": "concrete"}
CEILING_MATERIAL = {r: ("concrete" if r == CLOSED_ROOM else "ceiling_white") for r in ROOMS}

# Floors: rectangles (x range, z range, material) that tile each room's floor exactly.
FLOORS = {
    "living": [((1.2, 3.8), (1.8, 3.7), "rug"),
               ((0.0, 5.95), (0.0, 1.8), "oak_floor"), ((0.0, 5.95), (3.7, 4.95), "oak_floor"),
               ((0.0, 1.2), (1.8, 3.7), "oak_floor"), ((3.8, 5.95), (1.8, 3.7), "oak_floor")],
    "kitchen": [((6.05, 10.0), (0.0, 1.3), "floor_tiles"), ((6.05, 10.0), (1.3, 3.95), "floor_tiles")],
    "storage": [((6.05, 10.0), (4.05, 5.95), "concrete")],
    "bedroom": [((0.0, 2.2), (5.05, 9.0), "oak_floor"), ((2.2, 4.1), (5.05, 9.0), "oak_floor"),
                ((4.1, 5.95), (5.05, 9.0), "oak_floor")],
    "study":   [((6.05, 8.3), (6.05, 9.0), "oak_floor"), ((8.3, 10.0), (6.05, 9.0), "oak_floor")],
}

# Doors: (room a, room b, axis of the wall normal, [u0, u1] along the wall), 2.1 m high. Room a's
# face is at the lower coordinate along the axis.
DOOR_HEIGHT = 2.1
DOORS = [
    ("living", "kitchen", "x", (1.2, 2.1)),
    ("living", "bedroom", "z", (3.6, 4.5)),
    ("bedroom", "study", "x", (7.9, 8.8)),
]
# Windows: (room, wall side, [u0, u1] along the wall, [y0, y1]). Sides: x- x+ z- z+ (the room face at
# the low / high coordinate); u is z for x walls and x for z walls.
WINDOWS = [
    ("living", "z-", (0.9, 3.1), (0.9, 2.3)),
    ("living", "x-", (1.6, 3.2), (0.9, 2.3)),
    ("kitchen", "z-", (7.4, 8.9), (1.1, 2.2)),
    ("kitchen", "x+", (1.6, 2.8), (1.1, 2.2)),
    ("bedroom", "x-", (6.3, 7.7), (0.9, 2.2)),
    ("bedroom", "z+", (3.8, 5.0), (0.9, 2.2)),
    ("study", "z+", (7.4, 9.0), (0.9, 2.2)),
]
# Ceiling lights: (room, x range, z range).
LIGHTS = [
    ("living", (2.3, 3.5), (2.2, 2.8)),
    ("kitchen", (7.7, 8.3), (1.7, 2.3)),
    ("bedroom", (2.7, 3.3), (6.7, 7.3)),
    ("study", (7.7, 8.3), (7.2, 7.8)),
]


def legs(x0, x1, z0, z1, height, size=0.05):
    return [((x, 0.0, z), (x + size, height, z + size)) for x in (x0, x1 - size) for z in (z0, z1 - size)]


# Furniture: (room, name, material, [boxes (lo, hi)]).
FURNITURE = [
    ("living", "sofa", "sofa_fabric", [((1.2, 0.0, 4.70), (3.4, 0.85, 4.95)),      # back
                                       ((1.4, 0.0, 3.95), (3.2, 0.42, 4.70)),      # seat
                                       ((1.2, 0.0, 3.95), (1.4, 0.62, 4.70)),      # arms
                                       ((3.2, 0.0, 3.95), (3.4, 0.62, 4.70))]),
    ("living", "coffee_table", "table_wood", [((1.8, 0.0, 2.5), (2.9, 0.42, 3.1))]),
    ("living", "sideboard", "cupboard_paint", [((0.0, 0.0, 3.45), (0.45, 0.6, 4.8))]),
    ("living", "bookshelf", "shelf_wood", [((5.6, 0.0, 2.6), (5.95, 2.0, 4.2))]),
    ("kitchen", "counter", "cabinet_white", [((6.05, 0.0, 0.0), (10.0, 0.86, 0.6)),
                                             ((9.4, 0.0, 0.6), (10.0, 0.86, 3.3))]),
    ("kitchen", "worktop", "worktop_dark", [((6.05, 0.86, 0.0), (10.0, 0.9, 0.62)),
                                            ((9.38, 0.86, 0.62), (10.0, 0.9, 3.3))]),
    ("kitchen", "wall_cabinet", "cabinet_white", [((6.05, 1.45, 0.0), (7.2, 2.2, 0.35))]),
    ("kitchen", "dining_table", "table_wood", [((6.9, 0.72, 2.1), (8.3, 0.76, 3.0))]
     + legs(6.95, 8.25, 2.15, 2.95, 0.72)),
    ("bedroom", "bed", "bed_fabric", [((1.5, 0.0, 6.9), (3.1, 0.5, 8.9))]),
    ("bedroom", "headboard", "table_wood", [((1.45, 0.0, 8.9), (3.15, 1.0, 9.0))]),
    ("bedroom", "nightstands", "table_wood", [((0.95, 0.0, 8.55), (1.4, 0.5, 9.0)),
                                              ((3.2, 0.0, 8.55), (3.65, 0.5, 9.0))]),
    ("bedroom", "wardrobe", "cupboard_paint", [((5.35, 0.0, 5.6), (5.95, 2.2, 7.4))]),
    ("study", "desk", "table_wood", [((7.4, 0.72, 8.3), (9.0, 0.76, 9.0)),
                                     ((7.4, 0.0, 8.3), (7.85, 0.72, 9.0)),
                                     ((8.55, 0.0, 8.3), (9.0, 0.72, 9.0))]),
    ("study", "bookshelf", "shelf_wood", [((9.65, 0.0, 6.3), (10.0, 2.0, 7.8))]),
    ("storage", "shelves", "shelf_wood", [((6.5, 0.0, 5.5), (9.5, 1.8, 5.95))]),
    ("storage", "crates", "cupboard_paint", [((8.4, 0.0, 4.3), (9.2, 0.6, 4.9)),
                                             ((8.5, 0.6, 4.4), (9.1, 1.0, 4.8))]),
]

MATERIALS = [  # (name, Kd, Ke, comment)
    ("wall_paint", (0.80, 0.79, 0.75), None, ["off-white matt paint"]),
    ("wall_green", (0.62, 0.74, 0.58), None, ["pale green paint (kitchen)"]),
    ("wall_blue", (0.60, 0.68, 0.80), None, ["pale blue paint (bedroom)"]),
    ("wall_yellow", (0.82, 0.75, 0.52), None, ["pale yellow paint (study)"]),
    ("ceiling_white", (0.85, 0.85, 0.85), None, []),
    ("concrete", (0.50, 0.49, 0.47), None, ["bare concrete (shut storage room)"]),
    ("oak_floor", (0.45, 0.32, 0.20), None, []),
    ("floor_tiles", (0.62, 0.60, 0.56), None, ["light stone tiles"]),
    ("rug", (0.60, 0.16, 0.12), None, ["red wool rug"]),
    ("sofa_fabric", (0.22, 0.36, 0.32), None, ["teal fabric"]),
    ("table_wood", (0.55, 0.38, 0.22), None, []),
    ("shelf_wood", (0.40, 0.28, 0.18), None, ["walnut"]),
    ("cupboard_paint", (0.70, 0.66, 0.58), None, []),
    ("cabinet_white", (0.82, 0.82, 0.80), None, []),
    ("worktop_dark", (0.12, 0.12, 0.13), None, ["dark stone worktop"]),
    ("bed_fabric", (0.20, 0.28, 0.50), None, ["blue cover"]),
    ("led_panel", (0.80, 0.80, 0.80), (2.1, 2.0, 1.8), [
        "LED panel, luminance ~1800 cd m^-2: radiance ~5.9 W m^-2 sr^-1 in all, warm white",
        "(as in room.mtl). 0.72 m^2 in the living room (~4000 lm), 0.36 m^2 elsewhere (~2000 lm)."]),
    ("window_daylight", (0.08, 0.08, 0.08), (6.0, 6.6, 7.4), [
        "overcast sky of ~5000 cd m^-2 (~20 W m^-2 sr^-1 at ~250 lm/W), bluish, seen through glass;",
        "Kd 0.08: the little light glass reflects back (as in room.mtl)."]),
]

SIDES = {"x-": (0, 0, +1.0), "x+": (0, 1, -1.0), "z-": (2, 0, +1.0), "z+": (2, 1, -1.0)}  # axis, lo/hi, normal sign


def point(axis, value, u_axis, u, v_axis, v):
    p = [0.0, 0.0, 0.0]
    p[axis], p[u_axis], p[v_axis] = value, u, v
    return tuple(p)


def quads(axis, value, u_axis, us, v_axis, vs, normal, keep=lambda c: True):
    """Quads of the plane p[axis] = value on the grid us x vs with fronts along normal; keep(centre)."""
    out = []
    for u0, u1 in zip(us, us[1:]):
        for v0, v1 in zip(vs, vs[1:]):
            poly = [point(axis, value, u_axis, u, v_axis, v) for u, v in [(u0, v0), (u1, v0), (u1, v1), (u0, v1)]]
            if keep(centroid(poly)):
                out.append(oriented(poly, normal))
    return out


def unit(axis, sign):
    n = [0.0, 0.0, 0.0]
    n[axis] = sign
    return tuple(n)


def room_openings(room):
    """{side: [(u0, u1, y0, y1)]} of the door and window openings in each wall face of the room."""
    out = {s: [] for s in SIDES}
    for a, b, axis, (u0, u1) in DOORS:
        if room in (a, b):
            out[axis + ("+" if room == a else "-")].append((u0, u1, 0.0, DOOR_HEIGHT))
    for r, side, (u0, u1), (y0, y1) in WINDOWS:
        if r == room:
            out[side].append((u0, u1, y0, y1))
    return out


def tunnel(axis, c0, c1, u_axis, u0, u1, y0, y1):
    """Reveal faces lining a rectangular opening from plane c0 to plane c1 along axis, all facing its
    axis line: jambs at u0 and u1 (full height), head at y1 and sill/threshold at y0 (full width)."""
    ds = breaks(c0, c1, [], FURN)
    us = breaks(u0, u1, [], FURN)
    ys = breaks(y0, y1, [], FURN)
    polys = []
    polys += quads(u_axis, u0, axis, ds, 1, ys, unit(u_axis, +1.0))
    polys += quads(u_axis, u1, axis, ds, 1, ys, unit(u_axis, -1.0))
    polys += quads(1, y1, axis, ds, u_axis, us, (0.0, -1.0, 0.0))
    polys += quads(1, y0, axis, ds, u_axis, us, (0.0, 1.0, 0.0))
    return polys


def inside_box(p, lo, hi):
    return all(lo[k] < p[k] < hi[k] for k in range(3))


def furniture_polys(room, boxes_here, lo, hi):
    """Outward quads of box (lo, hi), omitting quads that touch the room's floor/walls/ceiling or
    another box (their centre, nudged 0.1 mm outward, is outside the room or inside another box).
    Each box is cut where touching boxes end, so contact areas are whole quads."""
    (rx, rz) = ROOMS[room]
    room_lo, room_hi = (rx[0], 0.0, rz[0]), (rx[1], H, rz[1])
    touching = [b for b in boxes_here if b != (lo, hi)
                and all(b[0][k] <= hi[k] + 1e-9 and lo[k] <= b[1][k] + 1e-9 for k in range(3))]
    grids = [breaks(lo[k], hi[k], [c for b in touching for c in (b[0][k], b[1][k])], FURN) for k in range(3)]
    polys = []
    for axis in range(3):
        u_axis, v_axis = [k for k in range(3) if k != axis]
        for sign, value in ((-1.0, lo[axis]), (1.0, hi[axis])):
            normal = unit(axis, sign)

            def keep(c):
                p = tuple(c[k] + 1e-4 * normal[k] for k in range(3))
                if not inside_box(p, room_lo, room_hi):
                    return False
                return not any(inside_box(p, b[0], b[1]) for b in touching)
            polys += quads(axis, value, u_axis, grids[u_axis], v_axis, grids[v_axis], normal, keep)
    return polys


def build():
    """[(group, material, polygons)] in file order, with every face's orientation checked."""
    objects = []

    def add(group, material, polys, facing):
        if not polys:
            return
        facing(polys)
        objects.append((group, material, polys))

    for room, ((x0, x1), (z0, z1)) in ROOMS.items():
        centre = ((x0 + x1) / 2, H / 2, (z0 + z1) / 2)
        faces_centre = lambda what: (lambda polys: check_facing(polys, centre, True, what))
        for k, ((fx0, fx1), (fz0, fz1), material) in enumerate(FLOORS[room]):
            polys = quads(1, 0.0, 0, breaks(fx0, fx1, [], WALL), 2, breaks(fz0, fz1, [], WALL), (0, 1, 0))
            add("%s/floor_%d" % (room, k + 1), material, polys, faces_centre(room + " floor"))
        polys = quads(1, H, 0, breaks(x0, x1, [], WALL), 2, breaks(z0, z1, [], WALL), (0, -1, 0))
        add(room + "/ceiling", CEILING_MATERIAL[room], polys, faces_centre(room + " ceiling"))
        openings = room_openings(room)
        ranges = [(x0, x1), None, (z0, z1)]
        for side, (axis, end, sign) in SIDES.items():
            u_axis = 2 if axis == 0 else 0
            value = ranges[axis][end]
            ops = openings[side]
            us = breaks(ranges[u_axis][0], ranges[u_axis][1], [c for o in ops for c in o[:2]], WALL)
            ys = breaks(0.0, H, [c for o in ops for c in o[2:]], WALL)
            solid = lambda c: not any(o[0] < c[u_axis] < o[1] and o[2] < c[1] < o[3] for o in ops)
            polys = quads(axis, value, u_axis, us, 1, ys, unit(axis, sign), solid)
            add("%s/wall_%s" % (room, side), WALL_MATERIAL[room], polys, faces_centre(room + " wall " + side))
        for r, side, (u0, u1), (y0, y1) in WINDOWS:
            if r != room:
                continue
            axis, end, sign = SIDES[side]
            u_axis = 2 if axis == 0 else 0
            face = ranges[axis][end]
            glass = face - sign * WINDOW_DEPTH
            name = "%s/window_%s" % (room, side)
            mid = [0.0, (y0 + y1) / 2, 0.0]
            mid[axis], mid[u_axis] = (face + glass) / 2, (u0 + u1) / 2
            add(name + "_reveal", WALL_MATERIAL[room], tunnel(axis, min(face, glass), max(face, glass), u_axis,
                                                               u0, u1, y0, y1),
                lambda polys: check_facing(polys, tuple(mid), True, name + " reveal"))
            glass_polys = quads(axis, glass, u_axis, breaks(u0, u1, [], WALL), 1, breaks(y0, y1, [], WALL),
                                unit(axis, sign))
            add(name, "window_daylight", glass_polys, faces_centre(name))
        for r, (lx0, lx1), (lz0, lz1) in LIGHTS:
            if r == room:
                polys = quads(1, H - LIGHT_DROP, 0, breaks(lx0, lx1, [], 0.3), 2, breaks(lz0, lz1, [], 0.3),
                              (0, -1, 0))
                add(room + "/ceiling_light", "led_panel", polys, faces_centre(room + " light"))
        boxes_here = [b for r, _, _, boxes in FURNITURE if r == room for b in boxes]
        for r, name, material, boxes in FURNITURE:
            if r != room:
                continue
            polys = []
            for lo, hi in boxes:
                box = furniture_polys(room, boxes_here, lo, hi)
                check_facing(box, centroid([lo, hi]), False, "%s/%s" % (room, name))
                polys += box
            add("%s/%s" % (room, name), material, polys, lambda p: None)

    for a, b, axis_name, (u0, u1) in DOORS:
        axis = "xyz".index(axis_name)
        u_axis = 2 if axis == 0 else 0
        c0 = ROOMS[a][axis // 2][1]   # room a's face (its high side)
        c1 = ROOMS[b][axis // 2][0]   # room b's face (its low side)
        if not c0 < c1:
            raise SystemExit("door %s-%s: rooms do not face each other across a wall" % (a, b))
        mid = [0.0, DOOR_HEIGHT / 2, 0.0]
        mid[axis], mid[u_axis] = (c0 + c1) / 2, (u0 + u1) / 2
        name = "door/%s-%s" % (a, b)
        add(name, WALL_MATERIAL[a], tunnel(axis, c0, c1, u_axis, u0, u1, 0.0, DOOR_HEIGHT),
            lambda polys: check_facing(polys, tuple(mid), True, name))
    return objects


def check_plan():
    """Doors join rooms whose faces are one wall thickness apart and overlap along the door; the
    shut room has no door, window or light."""
    for a, b, axis_name, (u0, u1) in DOORS:
        axis = "xyz".index(axis_name)
        other = 1 if axis == 0 else 0
        for r in (a, b):
            lo, hi = ROOMS[r][other]
            if not (lo < u0 < u1 < hi):
                raise SystemExit("door %s-%s does not fit in %s's wall" % (a, b, r))
        if abs(ROOMS[b][axis // 2][0] - ROOMS[a][axis // 2][1] - 0.1) > 1e-9:
            raise SystemExit("door %s-%s: wall is not 0.1 m thick" % (a, b))
    if any(CLOSED_ROOM in (a, b) for a, b, _, _ in DOORS) or any(w[0] == CLOSED_ROOM for w in WINDOWS) \
            or any(l[0] == CLOSED_ROOM for l in LIGHTS):
        raise SystemExit("the shut room must have no door, window or light")


STOREY = 3.0        # building mode: storey pitch (2.7 m room + 0.3 m slab)
WING_PITCH = (10.6, 9.6)  # building mode: wing offsets along x and z (0.6 m between exterior walls)


def copies(storeys, wings):
    """Offsets of the floor-plan copies of a building: `storeys` levels of `wings` wings, the wings in two
    rows (x along the row, z between the rows)."""
    return [(w // 2 * WING_PITCH[0], s * STOREY, w % 2 * WING_PITCH[1]) for s in range(storeys) for w in range(wings)]


def write(outdir, storeys=1, wings=1, basename="floorplan"):
    check_plan()
    objects = build()
    w = ObjWriter()
    offsets = copies(storeys, wings)
    for k, (dx, dy, dz) in enumerate(offsets):
        prefix = "" if len(offsets) == 1 else "s%dw%d/" % (k // wings, k % wings)
        for group, material, polys in objects:
            w.add(prefix + group, material, [[(p[0] + dx, p[1] + dy, p[2] + dz) for p in poly] for poly in polys])
    areas = {}
    for group, material, polys in objects:
        if material in ("led_panel", "window_daylight"):
            areas[material] = areas.get(material, 0.0) + len(offsets) * sum(
                math.sqrt(dot(n, n)) / 2 for n in map(newell, polys))
    header = [] if len(offsets) == 1 else [
        "Building: %d storeys x %d wings = %d copies of the floor plan below (storey pitch %.1f m; groups "
        "sSwW/ROOM/OBJECT; quads <= %.3g m on floors, walls and ceilings, <= %.3g m on furniture)."
        % (storeys, wings, len(offsets), STOREY, WALL, FURN), ""]
    w.write(os.path.join(outdir, basename + ".obj"), header + [
        "Furnished floor: living room, kitchen, bedroom, study (lit: ceiling light + daylit windows) and a",
        "shut storage room (no door, window or light; it must stay dark). Metres, y up, 2.7 m ceilings.",
        "Generated by scripts/make_floorplan.py (see its header for the plan). Every room is a closed box of",
        "inward faces; interior walls are 0.1 m thick (two faces); door openings have reveal faces (jambs, head,",
        "threshold); windows are 0.15 m deep openings closed by an emitting rectangle; furniture boxes face",
        "outward. Floors, walls and ceilings are meshed independently (quads <= 0.5 m, furniture <= 0.25 m):",
        "coplanar adjacent faces and T-junctions are intended. Groups: ROOM/OBJECT, door/ROOM-ROOM.",
    ], basename + ".mtl")
    materials = []
    for name, kd, ke, comment in MATERIALS:
        if ke is not None:
            a = areas[name]
            comment = comment + ["%.2f m^2 in all: power pi * A * Ke = (%.1f, %.1f, %.1f) W."
                                 % ((a,) + tuple(math.pi * a * k for k in ke))]
        materials.append((name, kd, ke, comment))
    write_mtl(os.path.join(outdir, basename + ".mtl"), [
        "Floor plan materials. Kd = diffuse reflectance, Ke = emitted radiance in W m^-2 sr^-1.",
        "Each channel carries about a third of the visible band: R + G + B = visible radiance.",
    ], materials)


# ---------------------------------------------------------------------------------------------------
# --check: read a lambert .vtu (VTK XML, appended raw, zlib) with the standard library.


def read_vtu_cell_arrays(path, names):
    with open(path, "rb") as f:
        data = f.read()
    start = data.index(b"<AppendedData")
    base = data.index(b"_", start) + 1
    head = data[:start].decode()
    root = ET.fromstring(head + ("</VTKFile>" if "</UnstructuredGrid>" in head else "</UnstructuredGrid></VTKFile>"))
    header = {"UInt32": "<I", "UInt64": "<Q"}[root.get("header_type", "UInt32")]
    hsize = struct.calcsize(header)
    compressed = root.get("compressor") == "vtkZLibDataCompressor"
    types = {"Float64": "d", "Float32": "f", "Int64": "q", "Int32": "i", "UInt8": "B"}
    out = {}
    for arr in root.find("UnstructuredGrid/Piece/CellData").iter("DataArray"):
        if arr.get("Name") not in names or arr.get("format") != "appended":
            continue
        pos = base + int(arr.get("offset"))
        if compressed:
            nblocks = struct.unpack_from(header, data, pos)[0]
            sizes = struct.unpack_from("<%d%s" % (nblocks, header[1]), data, pos + 3 * hsize)
            pos += (3 + nblocks) * hsize
            raw = b""
            for s in sizes:
                raw += zlib.decompress(data[pos:pos + s])
                pos += s
        else:
            n = struct.unpack_from(header, data, pos)[0]
            raw = data[pos + hsize:pos + hsize + n]
        code = types[arr.get("type")]
        values = struct.unpack("<%d%s" % (len(raw) // struct.calcsize(code), code), raw)
        k = int(arr.get("NumberOfComponents", "1"))
        out[arr.get("Name")] = [values[i:i + k] for i in range(0, len(values), k)]
    missing = [n for n in names if n not in out]
    if missing:
        raise SystemExit("%s: no cell array(s) %s" % (path, ", ".join(missing)))
    return out


def obj_face_groups(path):
    """Group name of every face of an OBJ, in file order."""
    groups, current = [], ""
    with open(path) as f:
        for line in f:
            words = line.split(None, 1)
            if not words:
                continue
            if words[0] in ("o", "g"):
                current = words[1].strip() if len(words) > 1 else ""
            elif words[0] == "f":
                groups.append(current)
    return groups


def check(vtu, obj):
    cells = read_vtu_cell_arrays(vtu, ["radiance", "irradiance", "emission", "face_id", "area"])
    groups = obj_face_groups(obj)
    if max(f for (f,) in cells["face_id"]) >= len(groups):
        raise SystemExit("%s does not come from %s: face ids beyond its %d faces" % (vtu, obj, len(groups)))
    rooms = {}
    for rad, irr, em, (fid,), (area,) in zip(cells["radiance"], cells["irradiance"], cells["emission"],
                                             cells["face_id"], cells["area"]):
        parts = groups[fid].split("/")
        if len(parts) > 2 and parts[0][:1] == "s" and "w" in parts[0]:  # building: sSwW/ROOM/OBJECT
            parts = parts[1:]
        room = parts[0]
        if room == "door":
            room = "doors"
        s = rooms.setdefault(room, {"patches": 0, "area": 0.0, "L_area": 0.0, "L_max": 0.0, "H_max": 0.0})
        s["patches"] += 1
        if max(em) > 0:
            continue
        L = sum(rad)  # R + G + B: visible radiance
        s["area"] += area
        s["L_area"] += L * area
        s["L_max"] = max(s["L_max"], L)
        s["H_max"] = max(s["H_max"], sum(irr))
    print("%-9s %7s %9s %12s %12s %12s" % ("room", "patches", "area m^2", "mean L", "max L", "max H"))
    print("%-9s %7s %9s %12s %12s %12s" % ("", "", "", "W/m2/sr", "W/m2/sr", "W/m2"))
    for room, s in rooms.items():
        mean = s["L_area"] / s["area"] if s["area"] else 0.0
        s["L_mean"] = mean
        print("%-9s %7d %9.2f %12.6g %12.6g %12.6g" % (room, s["patches"], s["area"], mean, s["L_max"], s["H_max"]))
    missing = [r for r in ROOMS if r not in rooms]
    if missing:
        raise SystemExit("%s has no patches of room(s) %s: not a solution of the floor plan" % (vtu, ", ".join(missing)))
    lit = [r for r in ROOMS if r != CLOSED_ROOM]
    dimmest = min(rooms[r]["L_mean"] for r in lit)
    leak = rooms[CLOSED_ROOM]["L_max"]
    print("(R + G + B of non-emitting patches; mean is area-weighted)")
    print("shut room %s: max radiance %.3g W m^-2 sr^-1, max irradiance %.3g W m^-2 (dimmest lit room mean %.3g)"
          % (CLOSED_ROOM, leak, rooms[CLOSED_ROOM]["H_max"], dimmest))
    # Nothing but a leak can light the shut room: without one, its rows and columns of F are exactly 0
    # and so is its radiance. 1e-9 of the dimmest lit room is only a margin for rounding.
    ok = leak <= 1e-9 * dimmest and dimmest > 0.1
    print("check:", "OK" if ok else "FAIL")
    return 0 if ok else 1


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default=os.path.join(here, os.pardir, "examples"), help="output directory")
    parser.add_argument("--check", metavar="VTU", help="report per-room radiance of a solution of floorplan.obj")
    parser.add_argument("--obj", default=None, help="with --check: the solved OBJ (default: OUT/floorplan.obj)")
    parser.add_argument("--building", type=int, metavar="FACES",
                        help="write building.obj + building.mtl instead: storeys and wings of copies of the floor plan "
                             "(every copy's storage room shut), about FACES faces in all (quads refined or coarsened "
                             "to get there); for scaling benchmarks (docs/benchmarks.md), not committed")
    parser.add_argument("--storeys", type=int, default=0, help="with --building: storeys (default: chosen)")
    args = parser.parse_args()
    if args.building:
        global WALL, FURN
        base = 3734  # faces of one floor plan at the default quad sizes
        n = max(1, args.building)
        copies_needed = max(1, round(n / base))
        storeys = args.storeys or max(1, min(20, copies_needed))
        wings = max(1, math.ceil(copies_needed / storeys))
        # Faces of a copy scale like 1 / quad size^2 (floors, walls, ceilings dominate).
        scale = math.sqrt(base * storeys * wings / n)
        WALL, FURN = 0.5 * scale, 0.25 * scale
        os.makedirs(args.out, exist_ok=True)
        print("building: %d storeys x %d wings, quads <= %.3g m (furniture %.3g m)" % (storeys, wings, WALL, FURN))
        write(args.out, storeys, wings, "building")
        return
    if args.check:
        sys.exit(check(args.check, args.obj or os.path.join(args.out, "floorplan.obj")))
    os.makedirs(args.out, exist_ok=True)
    write(args.out)


if __name__ == "__main__":
    main()
