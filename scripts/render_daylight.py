"""Render the work plane's daylight factor of a `lambert solve --sky ... --sensors-out OUT.csv` run: the room's
floor, walls and furniture (light grey; ceilings, seen from behind, culled) seen from above, the sensors of OUT.vtu as discs coloured
by daylight factor (%), with a colour bar.

  PYTHONPATH=/opt/lambert/paraview-python/usr/lib/python3/dist-packages \\
      xvfb-run -a pvbatch scripts/render_daylight.py ROOM.vtu SENSORS.vtu OUT.png [--up y]
"""
import sys

from paraview.simple import (ColorBy, CreateView, Delete, GetColorTransferFunction, GetScalarBar, GetViews,
                             Render, ResetCamera, SaveScreenshot, Show, Threshold, XMLUnstructuredGridReader,
                             Glyph)


def main():
    room_path, sensors_path, png = sys.argv[1:4]
    room = XMLUnstructuredGridReader(FileName=[room_path])
    room.UpdatePipeline()
    sensors = XMLUnstructuredGridReader(FileName=[sensors_path])
    sensors.UpdatePipeline()
    view = CreateView("RenderView")
    view.ViewSize = [1200, 900]
    if hasattr(view, "UseColorPaletteForBackground"):
        view.UseColorPaletteForBackground = 0
    view.Background = [1, 1, 1]
    view.OrientationAxesVisibility = 0
    # The room without the patches that face down (ceilings, lamps): seen from above.
    shown = Show(room, view)
    shown.Representation = "Surface"
    ColorBy(shown, None)
    shown.DiffuseColor = [0.75, 0.75, 0.75]
    shown.AmbientColor = [0.75, 0.75, 0.75]
    shown.BackfaceRepresentation = "Cull Backface"  # ceilings face down: seen from above, their backs are culled
    dots = Glyph(Input=sensors, GlyphType="Sphere")
    dots.ScaleArray = ["POINTS", "No scale array"]
    dots.ScaleFactor = 0.2
    dots.GlyphMode = "All Points"
    d = Show(dots, view)
    ColorBy(d, ("POINTS", "daylight_factor"))
    lut = GetColorTransferFunction("daylight_factor")
    lut.ApplyPreset("Turbo", True)
    lut.RescaleTransferFunction(0.0, 10.0)
    d.SetScalarBarVisibility(view, True)
    bar = GetScalarBar(lut, view)
    bar.Title = "daylight factor %"
    bar.ComponentTitle = ""
    bar.TitleColor = [0, 0, 0]
    bar.LabelColor = [0, 0, 0]
    ResetCamera(view)
    cam = view.GetActiveCamera()
    b = room.GetDataInformation().GetBounds()
    cx, cy, cz = (b[0] + b[1]) / 2, (b[2] + b[3]) / 2, (b[4] + b[5]) / 2
    cam.SetFocalPoint(cx, cy, cz)
    cam.SetPosition(cx, cy + 4 * max(b[1] - b[0], b[5] - b[4]), cz + 1e-3)
    cam.SetViewUp(0, 0, -1)
    ResetCamera(view)
    Render(view)
    SaveScreenshot(png, view, ImageResolution=[1200, 900])
    for v in list(GetViews()):
        Delete(v)


if __name__ == "__main__":
    main()
