"""Renders the deformed cube-obstacle solution with ParaView (pvbatch; Debian package paraview).

Usage (after `htfeti solve --problem cube-obstacle --elements 20,20,20 --subdomains 2,2,2
--obstacle-amplitude 10 --vtu cube.vtu`):
    xvfb-run -a pvbatch bench/render_cube.py cube.vtu docs/img/cube-obstacle.png 10
Warps the mesh by the displacement (scale 1: the cube sags by its own weight onto the obstacle),
colours it by the von Mises stress, and draws the obstacle surface z = -A sin(pi x / 50)."""
import math
import sys

from paraview.simple import (CellDatatoPointData, ColorBy, GetActiveViewOrCreate, Plane, Render,
                             SaveScreenshot, Show, XMLUnstructuredGridReader, Calculator, WarpByVector,
                             GetColorTransferFunction, Hide)

src, out = sys.argv[1], sys.argv[2]
amplitude = float(sys.argv[3]) if len(sys.argv) > 3 else 10.0
reader = XMLUnstructuredGridReader(FileName=[src])
reader.PointArrayStatus = ["u"]
reader.CellArrayStatus = ["von_mises", "subdomain"]
warp = WarpByVector(Input=reader)
warp.Vectors = ["POINTS", "u"]
warp.ScaleFactor = 1.0
view = GetActiveViewOrCreate("RenderView")
view.ViewSize = [1200, 900]
view.Background = [1, 1, 1]
view.OrientationAxesVisibility = 0
d = Show(warp, view)
ColorBy(d, ("CELLS", "von_mises"))
d.SetScalarBarVisibility(view, True)
lut = GetColorTransferFunction("von_mises")
lut.ApplyPreset("Viridis (matplotlib)", True)
# The obstacle surface, a thin plane warped by z = -A sin(pi x / 50).
plane = Plane(Origin=[-5, -10, 0], Point1=[105, -10, 0], Point2=[-5, 110, 0])
plane.XResolution = 110
plane.YResolution = 2
calc = Calculator(Input=plane)
calc.ResultArrayName = "obstacle"
calc.CoordinateResults = 1
calc.Function = f"coordsX*iHat + coordsY*jHat + (-{amplitude}*sin(3.14159265358979*coordsX/50))*kHat"
o = Show(calc, view)
o.DiffuseColor = [0.6, 0.6, 0.6]
o.Opacity = 0.6
o.ColorArrayName = [None, ""]
view.CameraPosition = [260, -220, 160]
view.CameraFocalPoint = [50, 50, 35]
view.CameraViewUp = [0, 0, 1]
Render(view)
SaveScreenshot(out, view, ImageResolution=[1200, 900])
print("wrote", out)
