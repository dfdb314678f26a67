"""Open a lambert .vtu in ParaView, check its radiance arrays, render it and check the picture.

Run with ParaView's batch interpreter (no display needed):
  PYTHONPATH=/opt/lambert/paraview-python/usr/lib/python3/dist-packages \
      xvfb-run -a pvbatch scripts/paraview_check.py IN.vtu OUT.png
Exit status 0 when the file opens with 3-component 'radiance' point and cell arrays and the saved PNG
shows the coloured model; 1 otherwise, with the reason on stderr.
"""
import os
import sys

from paraview import servermanager
from paraview.simple import (ColorBy, CreateView, Delete, GetColorTransferFunction, GetScalarBar, GetViews, LoadPalette, Render,
                             ResetCamera, SaveScreenshot, Show, XMLUnstructuredGridReader)
from vtkmodules.vtkCommonCore import vtkIdList
from vtkmodules.vtkIOImage import vtkPNGReader

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


def picture_stats(png):
    """(distinct colours among non-background pixels, fraction of non-background pixels)."""
    if not os.path.isfile(png) or os.path.getsize(png) == 0:
        fail("screenshot %s was not written" % png)
    reader = vtkPNGReader()
    reader.SetFileName(png)
    reader.Update()
    image = reader.GetOutput()
    scalars = image.GetPointData().GetScalars()
    if scalars is None or image.GetNumberOfPoints() == 0:
        fail("screenshot %s cannot be read back" % png)
    bg = tuple(int(round(255 * c)) for c in BACKGROUND)
    ncomp = min(3, scalars.GetNumberOfComponents())
    try:
        from vtkmodules.util.numpy_support import vtk_to_numpy
        import numpy
        pixels = vtk_to_numpy(scalars).reshape(image.GetNumberOfPoints(), -1)[:, :ncomp]
        fg = pixels[numpy.any(pixels != numpy.array(bg[:ncomp]), axis=1)]
        distinct = len(numpy.unique(fg, axis=0)) if len(fg) else 0
        return distinct, len(fg) / float(len(pixels))
    except ImportError:  # numpy is optional: slower pure-Python count
        colours, covered = set(), 0
        n = image.GetNumberOfPoints()
        for i in range(n):
            px = tuple(int(scalars.GetComponent(i, c)) for c in range(ncomp))
            if px != bg[:ncomp]:
                covered += 1
                colours.add(px)
        return len(colours), covered / float(n)


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
    SaveScreenshot(model_png, view, ImageResolution=[WIDTH, HEIGHT])
    distinct, coverage = picture_stats(model_png)
    os.remove(model_png)
    display.SetScalarBarVisibility(view, True)
    bar = GetScalarBar(GetColorTransferFunction("radiance"), view)
    bar.Title = "radiance magnitude"
    bar.ComponentTitle = "W m^-2 sr^-1"
    Render(view)
    SaveScreenshot(png, view, ImageResolution=[WIDTH, HEIGHT])
    final_distinct, final_coverage = picture_stats(png)

    lut_points = lut.RGBPoints
    print("paraview_check: %s: %d points, %d cells" % (vtu, info.GetNumberOfPoints(), info.GetNumberOfCells()))
    print("  point radiance |L| range %.6g .. %.6g W m^-2 sr^-1 (colour map %.6g .. %.6g)"
          % (point_radiance.GetRange(-1)[0], point_radiance.GetRange(-1)[1], lut_points[0], lut_points[-4]))
    print("  cell radiance  |L| range %.6g .. %.6g W m^-2 sr^-1" % cell_radiance.GetRange(-1))
    print("  %s: %dx%d; the model alone covers %.1f%% of the picture in %d distinct colours"
          % (png, WIDTH, HEIGHT, 100 * coverage, distinct))
    # The camera is fitted to the model, so a drawn model covers a good part of the picture; a colour-mapped
    # radiosity solution varies smoothly and so shows many colours. Blank or one flat colour means the
    # model, or its colouring, was not drawn. (A perfectly uniform radiance field would fail the second
    # test; lambert's solutions of real scenes never are.)
    if coverage < 0.10:
        fail("picture is blank: the model covers only %.2f%% of the picture" % (100 * coverage))
    if distinct < 16:
        fail("the model shows only %d distinct colours: radiance colouring missing" % distinct)
    if final_coverage < coverage or final_distinct < distinct:
        fail("%s (with legend) has less content than the model-only picture" % png)
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
