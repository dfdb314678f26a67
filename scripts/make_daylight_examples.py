#!/usr/bin/env python3
"""Writes the daylight variants of two examples (python3 stdlib only), for `lambert solve --sky`:

  examples/window_room_daylight.obj + .mtl   window_room.obj with its window glazed instead of emitting:
      material `glazing` (Kd 0.08, transmittance 0.70: clear double glazing's visible transmittance is
      ~0.7-0.8, and ~8 % is reflected), no emission; the sky outside lights the room through it.
  examples/floorplan_daylight.obj + .mtl     floorplan.obj with its seven windows opened to the sky (the
      emitting rectangles at the end of the window reveals are left out: the reveals frame an opening) and
      the LED panels switched off (Ke 0: a daylight factor counts daylight only).

Both keep every other face, vertex and material of the original (same face order, so face ids match up to
the removed faces). Usage: scripts/make_daylight_examples.py [--out DIR]
"""
import argparse
import os
import re


def variant(src_obj, dst_obj, src_mtl, dst_mtl, drop_material=None, rename=None, mtl_edit=None):
    with open(src_obj) as f:
        lines = f.read().split("\n")
    out, current, dropped = [], None, 0
    for line in lines:
        if line.startswith("mtllib "):
            line = "mtllib " + os.path.basename(dst_mtl)
        elif line.startswith("usemtl "):
            current = line.split(None, 1)[1].strip()
            if current == drop_material:
                continue
            if rename and current in rename:
                line = "usemtl " + rename[current]
        elif line.startswith("f ") and current == drop_material:
            dropped += 1
            continue
        out.append(line)
    with open(dst_obj, "w") as f:
        f.write("\n".join(out))
    with open(src_mtl) as f:
        mtl = f.read()
    with open(dst_mtl, "w") as f:
        f.write(mtl_edit(mtl))
    return dropped


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=os.path.join(here, os.pardir, "examples"))
    args = ap.parse_args()
    ex = os.path.join(here, os.pardir, "examples")

    def glazing(mtl):
        head = "# window_room.mtl with the window glazed (scripts/make_daylight_examples.py).\n"
        mtl = re.sub(r"# Overcast sky through the opening.*\Z", "", mtl, flags=re.S)
        return head + mtl + ("# Glazing: visible transmittance 0.70 (a lambert MTL extension), reflectance 0.08;\n"
                             "# lit from outside by --sky.\nnewmtl glazing\nKd 0.08 0.08 0.08\ntransmittance 0.70\n")

    variant(os.path.join(ex, "window_room.obj"), os.path.join(args.out, "window_room_daylight.obj"),
            os.path.join(ex, "window_room.mtl"), os.path.join(args.out, "window_room_daylight.mtl"),
            rename={"daylight": "glazing"}, mtl_edit=glazing)

    def no_lights(mtl):
        head = ("# floorplan.mtl for floorplan_daylight.obj (scripts/make_daylight_examples.py): the windows are\n"
                "# openings to the sky, the LED panels are off.\n")
        mtl = re.sub(r"(newmtl led_panel\n(?:.*\n)*?)Ke [^\n]*\n", r"\1Ke 0 0 0\n", mtl)
        mtl = re.sub(r"newmtl window_daylight\n(?:[^n#].*\n|\n)*", "", mtl)
        return head + mtl

    n = variant(os.path.join(ex, "floorplan.obj"), os.path.join(args.out, "floorplan_daylight.obj"),
                os.path.join(ex, "floorplan.mtl"), os.path.join(args.out, "floorplan_daylight.mtl"),
                drop_material="window_daylight", mtl_edit=no_lights)
    print("wrote window_room_daylight.obj/.mtl and floorplan_daylight.obj/.mtl (%d window faces opened)" % n)


if __name__ == "__main__":
    main()
