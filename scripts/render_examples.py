"""Render lambert solutions (.vtu) to PNG pictures coloured by radiance, with ParaView.

  PYTHONPATH=/opt/lambert/paraview-python/usr/lib/python3/dist-packages \
      xvfb-run -a pvbatch scripts/render_examples.py OUT_DIR VTU...

Each VTU gets a camera chosen from its file name (see PRESETS): `cornell*` -> the Cornell box's
published camera, `window_room*`, `room*` and `floorplan*` -> from above at an angle with the ceilings removed, anything
else -> the same kind of view over its bounding box. The picture is written to OUT_DIR/<preset>.png
(cornell_box.png, window_room.png, room.png, floorplan.png, or the VTU's base name).

Colour: for a colour scene every vertex shows its RGB radiance (point data 'radiance') as a colour,
L / L_white clipped to [0, 1] and raised to 1/2.2 for display, with L_white the 99th percentile of the
largest channel over the non-emitting patches (emitters and the brightest 1 % saturate to white). The
colours are passed to ParaView directly (MapScalars off), drawn unlit (ambient 1, diffuse 0) so a
pixel shows the radiance itself, not radiance times a headlight's shading. A grey scene (R = G = B
everywhere) is shown as radiance magnitude on a colour map with a colour bar instead. Surfaces are
one-sided: back faces are culled, so the camera sees into a room through the walls that face away.
"""
import math
import os
import sys

import paraview.simple
from paraview.simple import (ColorBy, CreateView, Delete, GetColorTransferFunction, GetScalarBar, GetViews,
                             PVTrivialProducer, Render, SaveScreenshot, Show, Text)
from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
from vtkmodules.vtkCommonDataModel import vtkDataObject
from vtkmodules.vtkFiltersCore import vtkFeatureEdges, vtkThreshold
from vtkmodules.vtkFiltersGeometry import vtkGeometryFilter
from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader
import numpy  # ships with ParaView's python

GAMMA = 2.2
PERCENTILE = 99.0

# name: (match in the file name, picture size, camera, ceiling removal, exposure factor on L_white,
# labels [(text, position, colour)]).
# Cameras: (position, focal point, view up, view angle in degrees), or ("orbit", elevation, azimuth)
# for default_camera's view at those angles, or None for default_camera's defaults. The Cornell box camera is the
# published one: (0.278, 0.273, -0.8) looking along +z, 35 mm focal length on a 25 mm film: a
# 2 atan(12.5 / 35) = 39.3 degree field of view.
PRESETS = [
    ("cornell_box", "cornell", (800, 800),
     ((0.278, 0.273, -0.8), (0.278, 0.273, 0.0), (0.0, 1.0, 0.0), 2 * math.degrees(math.atan(12.5 / 35.0))),
     False, 0.75, []),
    ("floorplan", "floorplan", (1280, 960), ("orbit", 70.0, 8.0), True, 0.6,
     [("living", (4.4, 0.3, 1.0), (1, 1, 1)), ("kitchen", (6.4, 0.3, 1.9), (1, 1, 1)),
      ("bedroom", (4.3, 0.3, 8.3), (1, 1, 1)), ("study", (6.5, 0.3, 6.6), (1, 1, 1)),
      ("storage (shut)", (6.5, 2.6, 4.7), (0.85, 0.85, 0.85))]),
    # Before "room", which its name also matches.
    ("window_room", "window_room", (1024, 768), ("orbit", 55.0, 35.0), True, 1.0, []),
    ("room", "room", (1024, 768), None, True, 1.0, []),
]


def close_views():
    # pvbatch dies with an X error (GLXBadContext) at exit if a render view is still alive.
    for view in list(GetViews()):
        Delete(view)


def preset_for(vtu):
    base = os.path.splitext(os.path.basename(vtu))[0]
    for name, match, size, camera, no_ceiling, exposure, labels in PRESETS:
        if match in base:
            return name, size, camera, no_ceiling, exposure, labels
    return base, (1024, 768), None, True, 1.0, []


def cell_geometry(grid):
    """(centroids, unit Newell normals) of every cell, N x 3 each."""
    offsets = vtk_to_numpy(grid.GetCells().GetOffsetsArray())
    conn = vtk_to_numpy(grid.GetCells().GetConnectivityArray())
    pts = vtk_to_numpy(grid.GetPoints().GetData())
    n = grid.GetNumberOfCells()
    centroids = numpy.zeros((n, 3))
    normals = numpy.zeros((n, 3))
    for c in range(n):
        p = pts[conn[offsets[c]:offsets[c + 1]]]
        q = numpy.roll(p, -1, axis=0)
        centroids[c] = p.mean(axis=0)
        normals[c] = 0.5 * numpy.cross(p, q).sum(axis=0)
    length = numpy.linalg.norm(normals, axis=1)
    normals /= numpy.where(length > 0, length, 1.0)[:, None]
    return centroids, normals


def prepare(vtu, no_ceiling, exposure):
    """The grid to draw (ceiling cells removed if asked), with the display colours or magnitude array.
    Returns (grid, lamps, mode, L_white): lamps = outlines of the removed emitting cells (ceiling
    lights) or None, mode 'rgb' or 'magnitude'."""
    reader = vtkXMLUnstructuredGridReader()
    reader.SetFileName(vtu)
    reader.Update()
    grid = reader.GetOutput()
    if grid.GetNumberOfCells() == 0:
        raise SystemExit("render_examples: %s has no cells" % vtu)
    for where, data in (("point", grid.GetPointData()), ("cell", grid.GetCellData())):
        arr = data.GetArray("radiance")
        if arr is None or arr.GetNumberOfComponents() != 3:
            raise SystemExit("render_examples: %s has no 3-component %s array 'radiance'" % (vtu, where))
    cell_rad = vtk_to_numpy(grid.GetCellData().GetArray("radiance"))
    emission = grid.GetCellData().GetArray("emission")
    emits = vtk_to_numpy(emission).max(axis=1) > 0 if emission is not None else numpy.zeros(len(cell_rad), bool)

    lamps = None
    if no_ceiling:
        # Ceilings and ceiling lights: faces looking down in the top tenth of the height. Seen from
        # above they are back faces anyway; removing them keeps a low camera from hiding the rooms.
        centroids, normals = cell_geometry(grid)
        lo, hi = grid.GetBounds()[2:4]
        ceiling = (normals[:, 1] < -0.9) & (centroids[:, 1] > hi - 0.1 * (hi - lo))
        # 2 = drawn, 1 = removed light (drawn as an outline), 0 = removed.
        keep = numpy.where(ceiling, numpy.where(emits, 1, 0), 2).astype(numpy.int8)
        arr = numpy_to_vtk(keep, deep=1)
        arr.SetName("keep")
        grid.GetCellData().AddArray(arr)

        def cells(lo, hi):
            threshold = vtkThreshold()
            threshold.SetInputData(grid)
            threshold.SetInputArrayToProcess(0, 0, 0, vtkDataObject.FIELD_ASSOCIATION_CELLS, "keep")
            threshold.SetLowerThreshold(lo)
            threshold.SetUpperThreshold(hi)
            threshold.Update()
            return threshold.GetOutput()
        if (keep == 1).any():
            surface = vtkGeometryFilter()
            surface.SetInputData(cells(0.5, 1.5))
            edges = vtkFeatureEdges()
            edges.SetInputConnection(surface.GetOutputPort())
            edges.BoundaryEdgesOn()
            edges.FeatureEdgesOff()
            edges.NonManifoldEdgesOff()
            edges.ManifoldEdgesOff()
            edges.ColoringOff()
            edges.Update()
            lamps = edges.GetOutput()
        grid = cells(1.5, 2.5)

    lit = cell_rad[~emits] if (~emits).any() else cell_rad
    grey = numpy.allclose(cell_rad[:, 0], cell_rad[:, 1]) and numpy.allclose(cell_rad[:, 1], cell_rad[:, 2])
    if grey:
        white = numpy.percentile(numpy.linalg.norm(lit, axis=1), PERCENTILE) * exposure
        return grid, lamps, "magnitude", white
    white = numpy.percentile(lit.max(axis=1), PERCENTILE) * exposure
    if not white > 0:
        white = max(cell_rad.max(), 1e-30)
    point_rad = vtk_to_numpy(grid.GetPointData().GetArray("radiance"))
    rgb = numpy.clip(point_rad / white, 0.0, 1.0) ** (1.0 / GAMMA)
    colours = numpy_to_vtk(numpy.rint(255 * rgb).astype(numpy.uint8), deep=1)
    colours.SetName("display_rgb")
    grid.GetPointData().AddArray(colours)
    return grid, lamps, "rgb", white


def default_camera(bounds, size, elevation=62.0, azimuth=8.0, angle=30.0, margin=0.04):
    """Looking at the bounding box from +z (turned `azimuth` degrees towards +x), `elevation` degrees
    above the horizon, as close as the box's corners allow with `margin` of the picture left free."""
    x0, x1, y0, y1, z0, z1 = bounds
    corners = numpy.array([(x, y, z) for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)])
    centre = corners.mean(axis=0)
    el, az = math.radians(elevation), math.radians(azimuth)
    back = numpy.array([math.sin(az) * math.cos(el), math.sin(el), math.cos(az) * math.cos(el)])  # to the eye
    right = numpy.cross((0.0, 1.0, 0.0), back)
    right /= numpy.linalg.norm(right)
    up = numpy.cross(back, right)
    tan_v = math.tan(math.radians(angle / 2)) * (1 - 2 * margin)
    tan_h = tan_v * size[0] / float(size[1])
    rel = corners - centre
    # Perspective: a corner at depth t in front of the eye must satisfy |x| <= t tan_h, |y| <= t tan_v.
    # Centre the picture on the corners' extent, then move back until every corner fits.
    for _ in range(2):
        def needed(offset_r, offset_u):
            d = 0.0
            for p in rel:
                x, y, z = p.dot(right) - offset_r, p.dot(up) - offset_u, p.dot(back)
                d = max(d, z + abs(x) / tan_h, z + abs(y) / tan_v)
            return d
        distance = needed(0.0, 0.0)
        xs = [p.dot(right) / (distance - p.dot(back)) for p in rel]
        ys = [p.dot(up) / (distance - p.dot(back)) for p in rel]
        shift_r = 0.5 * (max(xs) + min(xs)) * distance
        shift_u = 0.5 * (max(ys) + min(ys)) * distance
        centre = centre + shift_r * right + shift_u * up
        rel = corners - centre
    distance = needed(0.0, 0.0)
    return tuple(centre + distance * back), tuple(centre), tuple(up), angle


def render(vtu, out_dir):
    paraview.simple._DisableFirstRenderCameraReset()  # keep the camera set below
    name, size, camera, no_ceiling, exposure, labels = preset_for(vtu)
    grid, lamps, mode, white = prepare(vtu, no_ceiling, exposure)
    producer = PVTrivialProducer()
    producer.GetClientSideObject().SetOutput(grid)
    producer.UpdatePipeline()

    view = CreateView("RenderView")
    view.ViewSize = list(size)
    view.OrientationAxesVisibility = 0
    if hasattr(view, "UseColorPaletteForBackground"):  # ParaView >= 5.10
        view.UseColorPaletteForBackground = 0
    view.Background = [1.0, 1.0, 1.0]
    display = Show(producer, view)
    display.Ambient = 1.0
    display.Diffuse = 0.0
    display.Specular = 0.0
    display.BackfaceRepresentation = "Cull Backface"
    if mode == "rgb":
        ColorBy(display, ("POINTS", "display_rgb"))
        display.MapScalars = 0
        legend = ("colour = RGB radiance / %.3g W m^-2 sr^-1, clipped at 1, gamma %.1f"
                  % (white, GAMMA))
    else:
        ColorBy(display, ("POINTS", "radiance", "Magnitude"))
        lut = GetColorTransferFunction("radiance")
        lut.RescaleTransferFunction(0.0, white)
        lut.AutomaticRescaleRangeMode = "Never"
        display.SetScalarBarVisibility(view, True)
        bar = GetScalarBar(lut, view)
        bar.Title = "radiance magnitude"
        bar.ComponentTitle = "W m^-2 sr^-1"
        legend = "radiance magnitude, colour map clipped at %.3g W m^-2 sr^-1" % white
    if lamps is not None and lamps.GetNumberOfCells() > 0:
        # The removed ceiling lights, as outlines where they hang.
        lamp_source = PVTrivialProducer()
        lamp_source.GetClientSideObject().SetOutput(lamps)
        lamp_display = Show(lamp_source, view)
        ColorBy(lamp_display, None)
        lamp_display.AmbientColor = lamp_display.DiffuseColor = [1.0, 0.85, 0.2]
        lamp_display.Ambient = 1.0
        lamp_display.Diffuse = 0.0
        lamp_display.LineWidth = 2.5
        legend += "; ceilings removed, ceiling lights outlined in yellow"
    for label, position, colour in labels:
        label_display = Show(Text(Text=label), view)
        label_display.TextPropMode = "Billboard 3D Text"
        label_display.BillboardPosition = list(position)
        label_display.FontSize = 15
        label_display.Bold = 1
        label_display.Color = list(colour)
        label_display.Shadow = 1
    text = Text(Text="%s  (lambert; %s)" % (os.path.basename(vtu), legend))
    text_display = Show(text, view)
    text_display.FontSize = 13
    text_display.Color = [0.2, 0.2, 0.2]
    text_display.WindowLocation = "Lower Left Corner"
    text_display.BackgroundColor = [1.0, 1.0, 1.0, 0.7]
    text_display.ShowBorder = "Always"
    text_display.BorderThickness = 0

    if camera is None:
        camera = default_camera(grid.GetBounds(), size)
    elif camera[0] == "orbit":  # ("orbit", elevation, azimuth) in degrees
        camera = default_camera(grid.GetBounds(), size, elevation=camera[1], azimuth=camera[2])
    position, focal, up, angle = camera
    view.CameraPosition = list(position)
    view.CameraFocalPoint = list(focal)
    view.CameraViewUp = list(up)
    view.CameraViewAngle = angle
    view.CameraParallelProjection = 0
    Render(view)
    png = os.path.join(out_dir, name + ".png")
    SaveScreenshot(png, view, ImageResolution=list(size))
    print("render_examples: %s -> %s (%dx%d, %s, white = %.4g W m^-2 sr^-1, %d cells drawn)"
          % (vtu, png, size[0], size[1], mode, white, grid.GetNumberOfCells()))
    Delete(view)


def main(argv):
    if len(argv) < 3:
        sys.stderr.write(__doc__)
        return 2
    out_dir = argv[1]
    os.makedirs(out_dir, exist_ok=True)
    for vtu in argv[2:]:
        if not os.path.isfile(vtu):
            raise SystemExit("render_examples: %s does not exist" % vtu)
        render(vtu, out_dir)
    return 0


if __name__ == "__main__":
    try:
        status = main(sys.argv)
    finally:
        close_views()
    sys.exit(status)
