"""Renders an assembly solved by htfeti with ParaView (pvbatch; Debian package paraview): the
mesh warped by the displacement, coloured by the von Mises stress, the subdomain edges shown.

Usage (after `htfeti solve examples/punch-on-block.toml`, which writes punch-on-block.vtu):
    xvfb-run -a pvbatch bench/render_assembly.py examples/punch-on-block.vtu \\
        docs/img/punch-on-block.png 100
The last argument scales the displacement."""
import sys

from paraview.simple import (ColorBy, GetActiveViewOrCreate, GetColorTransferFunction,
                             GetScalarBar, Render, SaveScreenshot, Show, WarpByVector,
                             XMLUnstructuredGridReader)

src, out = sys.argv[1], sys.argv[2]
scale = float(sys.argv[3]) if len(sys.argv) > 3 else 1.0
reader = XMLUnstructuredGridReader(FileName=[src])
reader.PointArrayStatus = ["u"]
reader.CellArrayStatus = ["von_mises"]
warp = WarpByVector(Input=reader)
warp.Vectors = ["POINTS", "u"]
warp.ScaleFactor = scale
view = GetActiveViewOrCreate("RenderView")
view.ViewSize = [1200, 900]
view.UseColorPaletteForBackground = 0
view.Background = [1, 1, 1]
view.OrientationAxesVisibility = 0
d = Show(warp, view)
d.SetRepresentationType("Surface With Edges")
d.EdgeColor = [0.2, 0.2, 0.2]
ColorBy(d, ("CELLS", "von_mises"))
d.SetScalarBarVisibility(view, True)
lut = GetColorTransferFunction("von_mises")
lut.ApplyPreset("Cool to Warm", True)
bar = GetScalarBar(lut, view)
bar.Title = "von Mises stress"
bar.ComponentTitle = ""
bar.TitleColor = [0, 0, 0]
bar.LabelColor = [0, 0, 0]
view.CameraPosition = [2.6, -1.9, 2.4]
view.CameraFocalPoint = [0.5, 0.5, 0.6]
view.CameraViewUp = [0, 0, 1]
view.ResetCamera()
Render(view)
SaveScreenshot(out, view, ImageResolution=[1200, 900])
