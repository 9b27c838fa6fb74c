"""The XDMF output as ParaView reads it: ParaView's XDMF reader (pvbatch; Debian packages
paraview and python3-paraview, which scripts/setup.sh does not install) opens FILE.xdmf, its VTU
reader the VTU or PVTU of the same run, and every point and cell array and the points are
compared (NaN, the contact fields off the contact surface, equal to NaN).

Usage: build/htfeti solve PROBLEM --vtu u.pvtu --xdmf u.xdmf   (any number of ranks), then
       xvfb-run -a pvbatch bench/xdmf_in_paraview.py u.xdmf u.pvtu
Prints one line per array and exits 1 if any differs."""
import sys

import numpy as np
from paraview import servermanager as sm
from paraview.simple import MergeBlocks, XDMFReader, XMLPartitionedUnstructuredGridReader, \
    XMLUnstructuredGridReader
from vtkmodules.util.numpy_support import vtk_to_numpy

xdmf, vtu = sys.argv[1], sys.argv[2]
a = sm.Fetch(MergeBlocks(Input=XDMFReader(FileNames=[xdmf])))
reader = (XMLPartitionedUnstructuredGridReader if vtu.endswith(".pvtu")
          else XMLUnstructuredGridReader)(FileName=[vtu])
b = sm.Fetch(MergeBlocks(Input=reader))
print(f"XDMF: {a.GetNumberOfPoints()} points, {a.GetNumberOfCells()} cells; "
      f"VTU: {b.GetNumberOfPoints()} points, {b.GetNumberOfCells()} cells")
bad = a.GetNumberOfPoints() != b.GetNumberOfPoints() or a.GetNumberOfCells() != b.GetNumberOfCells()
pairs = [("points", a.GetPoints().GetData(), b.GetPoints().GetData())]
for da, db in ((a.GetPointData(), b.GetPointData()), (a.GetCellData(), b.GetCellData())):
    for i in range(db.GetNumberOfArrays()):
        name = db.GetArrayName(i)
        pairs.append((name, da.GetArray(name), db.GetArray(name)))
for name, x, y in pairs:
    same = x is not None and np.array_equal(vtk_to_numpy(x).reshape(-1),
                                            vtk_to_numpy(y).reshape(-1), equal_nan=True)
    print(f"  {name}: {'identical' if same else 'DIFFERS'}")
    bad = bad or not same
sys.exit(1 if bad else 0)
