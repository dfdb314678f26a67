"""Open a lambert .vtu in ParaView, check its radiance arrays, render it and check the picture.

Run with ParaView's batch interpreter (no display needed):
  PYTHONPATH=/opt/lambert/paraview-python/usr/lib/python3/dist-packages \
      xvfb-run -a pvbatch scripts/paraview_check.py IN.vtu OUT.png
Exit status 0 when the file opens with 3-component 'radiance' point and cell arrays and the saved PNG
shows the model coloured by point radiance; 1 otherwise, with the reason on stderr.
"""
import os
import sys

from paraview import servermanager
from paraview.simple import (ColorBy, CreateView, Delete, GetColorTransferFunction, GetScalarBar, GetViews,
                             LoadPalette, Render, ResetCamera, SaveScreenshot, Show, XMLUnstructuredGridReader)
from vtkmodules.vtkCommonCore import vtkIdList
from vtkmodules.vtkIOImage import vtkPNGReader
from vtkmodules.util.numpy_support import vtk_to_numpy
import numpy  # ships with ParaView's python

WIDTH, HEIGHT = 1024, 768
BACKGROUND = (1.0, 1.0, 1.0)  # plain white, so covered pixels are easy to count


class CheckFailed(Exception):
    pass


def fail(message):
    raise CheckFailed(message)


def close_views():
    # pvbatch dies with an X error (GLXBadContext) at exit if a render view is still alive.
    for view in list(GetViews()):
        Delete(view)


def array_info(info, name, where):
    arr = info.GetArray(name)
    if arr is None:
        names = [info.GetArray(i).GetName() for i in range(info.GetNumberOfArrays())]
        fail("no %s array '%s' (arrays: %s)" % (where, name, ", ".join(names) or "none"))
    if arr.GetNumberOfComponents() != 3:
        fail("%s array '%s' has %d components, expected 3" % (where, name, arr.GetNumberOfComponents()))
    return arr


def model_pixels(png):
    """(fraction of pixels that are not background, N x 3 array of those pixels' RGB, 0..255)."""
    if not os.path.isfile(png) or os.path.getsize(png) == 0:
        fail("screenshot %s was not written" % png)
    reader = vtkPNGReader()
    reader.SetFileName(png)
    reader.Update()
    image = reader.GetOutput()
    scalars = image.GetPointData().GetScalars()
    if scalars is None or image.GetNumberOfPoints() == 0 or scalars.GetNumberOfComponents() < 3:
        fail("screenshot %s cannot be read back as an RGB image" % png)
    pixels = vtk_to_numpy(scalars).reshape(image.GetNumberOfPoints(), -1)[:, :3].astype(int)
    background = numpy.rint(255 * numpy.array(BACKGROUND)).astype(int)
    fg = pixels[numpy.any(pixels != background, axis=1)]
    return len(fg) / float(len(pixels)), fg


def on_colour_map(pixels, lut, low, high):
    """Fraction of pixels whose colour is one of the colour map's (within 3 of 255 per channel)."""
    if len(pixels) == 0:
        return 0.0
    ctf = lut.GetClientSideObject()
    rgb = [0.0, 0.0, 0.0]
    samples = []
    for k in range(1025):  # dense enough that neighbouring samples differ by < 1 level
        ctf.GetColor(low + (high - low) * k / 1024.0, rgb)
        samples.append([255 * c for c in rgb])
    samples = numpy.array(samples)
    colours, counts = numpy.unique(pixels, axis=0, return_counts=True)
    distance = numpy.abs(colours[:, None, :] - samples[None, :, :]).max(axis=2).min(axis=1)
    return counts[distance <= 3].sum() / float(counts.sum())


def colour_range(reader):
    """(min, max) of the point radiance magnitude, the max over points of non-emitting cells only
    (falls back to the full range when every cell emits or the arrays are not there)."""
    grid = servermanager.Fetch(reader)
    radiance = grid.GetPointData().GetArray("radiance")
    full = radiance.GetRange(-1)
    emission = grid.GetCellData().GetArray("emission")
    if emission is None:
        return full
    high = None
    ids = vtkIdList()
    for c in range(grid.GetNumberOfCells()):
        if max(emission.GetTuple3(c)) > 0:
            continue
        grid.GetCellPoints(c, ids)
        for k in range(ids.GetNumberOfIds()):
            r, g, b = radiance.GetTuple3(ids.GetId(k))
            m = (r * r + g * g + b * b) ** 0.5
            high = m if high is None or m > high else high
    if high is None or not high > full[0]:
        return full
    return full[0], high


def main(argv):
    if len(argv) != 3:
        fail("usage: pvbatch paraview_check.py IN.vtu OUT.png")
    vtu, png = argv[1], argv[2]
    if not os.path.isfile(vtu):
        fail("input file %s does not exist" % vtu)

    reader = XMLUnstructuredGridReader(FileName=[vtu])
    reader.UpdatePipeline()
    info = reader.GetDataInformation()
    if info.GetNumberOfCells() == 0:
        fail("%s has no cells" % vtu)
    point_radiance = array_info(reader.GetPointDataInformation(), "radiance", "point")
    cell_radiance = array_info(reader.GetCellDataInformation(), "radiance", "cell")

    LoadPalette("WhiteBackground")  # white background, dark text for the colour legend
    view = CreateView("RenderView")
    view.ViewSize = [WIDTH, HEIGHT]
    view.OrientationAxesVisibility = 0
    if hasattr(view, "UseColorPaletteForBackground"):  # ParaView >= 5.10
        view.UseColorPaletteForBackground = 0
    view.Background = list(BACKGROUND)
    display = Show(reader, view)
    ColorBy(display, ("POINTS", "radiance", "Magnitude"))
    # Unlit: the colour shows the radiance itself, not radiance times a headlight's shading.
    display.Ambient = 1.0
    display.Diffuse = 0.0
    # Surfaces are one-sided: hide back faces, so the camera looks into a closed room through its
    # near wall (whose front faces away) instead of at that wall's back.
    display.BackfaceRepresentation = "Cull Backface"
    # Emitters are far brighter than everything they light; a colour map up to their radiance would show
    # every other surface in one dark colour. Map up to the brightest non-emitting surface; emitters saturate.
    low, high = colour_range(reader)
    lut = GetColorTransferFunction("radiance")
    lut.RescaleTransferFunction(low, high)
    lut.AutomaticRescaleRangeMode = "Never"
    # Look along +z with +y up: the Cornell box's published camera direction (its open side faces -z);
    # lambert's examples use y up.
    view.CameraPosition = [0.0, 0.0, -1.0]
    view.CameraFocalPoint = [0.0, 0.0, 0.0]
    view.CameraViewUp = [0.0, 1.0, 0.0]
    ResetCamera(view)

    # First the model alone (the colour legend would count as drawn pixels), then the picture with legend.
    model_png = os.path.splitext(png)[0] + ".model-only.png"
    Render(view)
    try:
        SaveScreenshot(model_png, view, ImageResolution=[WIDTH, HEIGHT])
        coverage, pixels = model_pixels(model_png)
    finally:
        if os.path.exists(model_png):
            os.remove(model_png)
    mapped = on_colour_map(pixels, lut, low, high)
    distinct = len(numpy.unique(pixels, axis=0)) if len(pixels) else 0
    display.SetScalarBarVisibility(view, True)
    bar = GetScalarBar(lut, view)
    bar.Title = "radiance magnitude"
    bar.ComponentTitle = "W m^-2 sr^-1"
    Render(view)
    SaveScreenshot(png, view, ImageResolution=[WIDTH, HEIGHT])
    final_coverage, _ = model_pixels(png)

    print("paraview_check: %s: %d points, %d cells" % (vtu, info.GetNumberOfPoints(), info.GetNumberOfCells()))
    print("  point radiance |L| range %.6g .. %.6g W m^-2 sr^-1 (colour map %.6g .. %.6g)"
          % (point_radiance.GetRange(-1)[0], point_radiance.GetRange(-1)[1], low, high))
    print("  cell radiance  |L| range %.6g .. %.6g W m^-2 sr^-1" % cell_radiance.GetRange(-1))
    print("  %s: %dx%d; the model alone covers %.1f%% of the picture, %d distinct colours, %.1f%% of its"
          " pixels in colour-map colours" % (png, WIDTH, HEIGHT, 100 * coverage, distinct, 100 * mapped))
    # The camera is fitted to the model, so a drawn model covers a good part of the picture, and it is
    # drawn unlit, so its pixels carry colour-map colours (only edge pixels are blends with the background).
    # Blank, or drawn in a solid colour instead of the radiance colours, fails.
    if coverage < 0.10:
        fail("picture is blank: the model covers only %.2f%% of the picture" % (100 * coverage))
    if mapped < 0.5:
        fail("only %.1f%% of the model's pixels show colour-map colours: not coloured by radiance" % (100 * mapped))
    if final_coverage < coverage:
        fail("%s (with legend) shows less than the model-only picture" % png)
    print("paraview_check: OK")
    return 0


if __name__ == "__main__":
    try:
        status = main(sys.argv)
    except CheckFailed as e:
        sys.stderr.write("paraview_check: FAIL: %s\n" % e)
        status = 1
    close_views()
    sys.exit(status)
