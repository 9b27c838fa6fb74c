#!/usr/bin/python3
"""The VTU output as ParaView reads it: htfeti solves small problems and VTK's own XML readers
(vtkXMLUnstructuredGridReader, vtkXMLPUnstructuredGridReader: what ParaView and pvpython use;
Debian package python3-vtk9) read the files back. Each file is checked against the report of
the same run, which the solver computes from its own arrays, not from the file:
  - the reader reports no error or warning, and the points are the subdomains' nodes with their
    copies (report: primal_dimension / dofs per node);
  - every cell has the element's VTK type and only valid point ids;
  - the displacement magnitudes: their maximum is the report's max_norm, and their mean over
    the distinct nodes (copies found by their coordinates) is its mean_norm, both to round-off:
    a value written to another point's place would change one or the other;
  - copies of a node carry the same u up to the solver's equality residual (the gluing rows
    have unit norm), except on contact interfaces, where copies of two bodies meet;
  - the cell arrays subdomain, cluster and rank take every value of their range;
  - contact problems: the gap is defined on at least one node per inequality and never below
    minus the report's largest violation; elasticity: the von Mises stress is finite and >= 0.
Every run also writes the XDMF output (--xdmf); its HDF5 file, read by h5py (Debian package
python3-h5py) through the datasets the XDMF text names, must hold the VTU's points, cells and
arrays bit for bit, with the dimensions the XDMF text declares (ranks in order in both).
Usage: tests/vtu_readable.py HTFETI MPIEXEC [MPIEXEC_FLAGS...]"""
import json
import math
import os
import subprocess
import sys
import tempfile

import xml.etree.ElementTree as ET

import h5py
import numpy as np
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkCommand
from vtkmodules.vtkIOXML import vtkXMLPUnstructuredGridReader, vtkXMLUnstructuredGridReader

HTFETI, MPIEXEC, FLAGS = sys.argv[1], sys.argv[2], sys.argv[3:]
VTK_TYPES = {"q1": 9, "p1": 5, "quad4": 9, "tri3": 5, "hex8": 12, "tet4": 10}
failures = []


def check(cond, what):
    if not cond:
        failures.append(what)
        print("  FAILED:", what)
    return cond


class Errors:
    """Collects the reader's errors and warnings (VTK prints and continues otherwise)."""
    def __init__(self, obj):
        self.messages = []
        for event in (vtkCommand.ErrorEvent, vtkCommand.WarningEvent):
            obj.AddObserver(event, lambda o, e, data=None: self.messages.append(e))


def read(path):
    reader = (vtkXMLPUnstructuredGridReader if path.endswith(".pvtu")
              else vtkXMLUnstructuredGridReader)()
    errors = Errors(reader)
    reader.SetFileName(path)
    reader.Update()
    return reader.GetOutput(), errors.messages


def array(grid, where, name):
    data = grid.GetPointData() if where == "point" else grid.GetCellData()
    a = data.GetArray(name)
    return None if a is None else vtk_to_numpy(a)


XDMF_TOPOLOGY = {5: "Triangle", 9: "Quadrilateral", 10: "Tetrahedron", 12: "Hexahedron"}


def check_xdmf(name, xdmf, grid):
    """The XDMF text's datasets against the VTU grid read by VTK."""
    if not check(os.path.exists(xdmf) and os.path.exists(xdmf[:-5] + ".h5"),
                 f"{name}: no XDMF output"):
        return
    root = ET.parse(xdmf).getroot()
    g = root.find("Domain/Grid")
    folder = os.path.dirname(xdmf)

    def data(item):
        file, path = item.text.strip().split(":")
        dims = [int(v) for v in item.get("Dimensions").split()]
        with h5py.File(os.path.join(folder, file), "r") as f:
            values = f[path][()]
        check(list(values.shape) == dims, f"{name}: {path} is {values.shape}, XDMF says {dims}")
        return values
    n_points, n_cells = grid.GetNumberOfPoints(), grid.GetNumberOfCells()
    topo = g.find("Topology")
    types = vtk_to_numpy(grid.GetCellTypesArray())
    check(topo.get("TopologyType") == XDMF_TOPOLOGY.get(int(types[0])) and
          int(topo.get("NumberOfElements")) == n_cells, f"{name}: XDMF topology {topo.attrib}")
    cells = data(topo.find("DataItem"))
    conn = vtk_to_numpy(grid.GetCells().GetConnectivityArray())
    check(np.array_equal(cells.reshape(-1), conn), f"{name}: XDMF cells differ from the VTU's")
    points = data(g.find("Geometry/DataItem"))
    check(np.array_equal(points, vtk_to_numpy(grid.GetPoints().GetData())),
          f"{name}: XDMF points differ from the VTU's")
    names = []
    for att in g.findall("Attribute"):
        where = "point" if att.get("Center") == "Node" else "cell"
        values = data(att.find("DataItem"))
        ref = array(grid, where, att.get("Name"))
        names.append(att.get("Name"))
        check(ref is not None and values.shape[0] == (n_points if where == "point" else n_cells)
              and np.array_equal(values.reshape(ref.shape), ref, equal_nan=True),
              f"{name}: XDMF {att.get('Name')} differs from the VTU's")
    data_vtu = [grid.GetPointData().GetArrayName(i)
                for i in range(grid.GetPointData().GetNumberOfArrays())]
    data_vtu += [grid.GetCellData().GetArrayName(i)
                 for i in range(grid.GetCellData().GetNumberOfArrays())]
    check(sorted(names) == sorted(data_vtu), f"{name}: XDMF arrays {names}, VTU {data_vtu}")


def run_case(name, args, ranks):
    print(f"{name}: htfeti solve {' '.join(args)} ({ranks} rank{'s' if ranks > 1 else ''})")
    with tempfile.TemporaryDirectory() as d:
        vtu = os.path.join(d, "u.pvtu" if ranks > 1 else "u.vtu")
        report_file = os.path.join(d, "r.json")
        xdmf = os.path.join(d, "u.xdmf")
        cmd = [HTFETI, "solve", *args, "--report", report_file, "--vtu", vtu, "--xdmf", xdmf]
        if ranks > 1:
            cmd = [MPIEXEC, "-n", str(ranks), *FLAGS, *cmd]
        env = dict(os.environ, OMP_NUM_THREADS="1")
        done = subprocess.run(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                              text=True)
        if not check(done.returncode == 0, f"{name}: exit {done.returncode}: {done.stderr}"):
            return
        with open(report_file) as f:
            r = json.load(f)
        grid, messages = read(vtu)
        check(not messages, f"{name}: the reader reported {messages}")
        n_points, n_cells = grid.GetNumberOfPoints(), grid.GetNumberOfCells()
        elastic = r["physics"]["type"] != "laplace"
        u = array(grid, "point", "u")
        if not check(u is not None, f"{name}: no point array u"):
            return
        check_xdmf(name, xdmf, grid)
        u = u.reshape(n_points, -1)
        dpn = r["primal_dimension"] // n_points if n_points else 0
        check(n_points * dpn == r["primal_dimension"] and (dpn == 1) != elastic,
              f"{name}: {n_points} points for {r['primal_dimension']} unknowns")
        check(u.shape[1] == (3 if elastic else 1), f"{name}: u has {u.shape[1]} components")
        types = vtk_to_numpy(grid.GetCellTypesArray()) if n_cells else np.array([])
        expected = VTK_TYPES.get(r["element"])
        check(n_cells > 0 and np.all(types == expected),
              f"{name}: cell types {set(types.tolist())}, expected {expected} ({r['element']})")
        conn = vtk_to_numpy(grid.GetCells().GetConnectivityArray())
        check(conn.size > 0 and conn.min() >= 0 and conn.max() < n_points,
              f"{name}: connectivity outside [0, {n_points})")
        norms = np.linalg.norm(u, axis=1)
        disp = r["displacement"]
        check(math.isclose(norms.max(), disp["max_norm"], rel_tol=1e-13),
              f"{name}: max |u| {norms.max()} against the report's {disp['max_norm']}")
        gap = array(grid, "point", "contact_gap")
        interface = np.zeros(n_points, dtype=bool)
        if r["inequalities"] > 0:
            if check(gap is not None and array(grid, "point", "contact_force") is not None,
                     f"{name}: contact arrays missing"):
                defined = ~np.isnan(gap)
                interface = defined
                check(defined.sum() >= r["inequalities"],
                      f"{name}: gap on {defined.sum()} nodes for {r['inequalities']} rows")
                worst = r["kkt"]["max_violation"]
                check(gap[defined].min() >= -worst * (1 + 1e-9) - 1e-14,
                      f"{name}: gap {gap[defined].min()} below -{worst}")
        # Friction: the state of every contact node with friction (0 open, 1 stick, 2 slip),
        # counted once per node, as the report counts them per condition.
        summary = r.get("contact_summary", [])
        if any("stick_nodes" in c for c in summary):
            state = array(grid, "point", "contact_state")
            if check(state is not None and array(grid, "point", "tangential_traction") is not None
                     and array(grid, "point", "contact_slip") is not None,
                     f"{name}: friction arrays missing"):
                xyz0 = vtk_to_numpy(grid.GetPoints().GetData())
                k0 = np.round(xyz0 / max(1e-300, np.abs(xyz0).max()) * 2**36).astype(np.int64)
                for value, key in ((0, "open_nodes"), (1, "stick_nodes"), (2, "slip_nodes")):
                    at = np.unique(k0[state == value], axis=0).shape[0]
                    want = sum(c.get(key, 0) for c in summary)
                    check(at == want, f"{name}: {at} nodes in state {value}, the report {want}")
        # Distinct nodes: points with the same coordinates (rounded far below the mesh size) in
        # the same body. Bodies: subdomains joined through shared points off contact interfaces
        # (where two bodies' nodes share coordinates).
        xyz = vtk_to_numpy(grid.GetPoints().GetData())
        keys = np.round(xyz / max(1e-300, np.abs(xyz).max()) * 2**36).astype(np.int64)
        _, place = np.unique(keys, axis=0, return_inverse=True)
        place = place.reshape(-1)
        cell_sub = array(grid, "cell", "subdomain")
        point_sub = np.full(n_points, -1)
        point_sub[conn] = np.repeat(cell_sub, conn.size // n_cells)
        parent = list(range(r["subdomains"]))

        def find(a):
            while parent[a] != a:
                parent[a] = parent[parent[a]]
                a = parent[a]
            return a
        first = {}
        for p in np.flatnonzero(~interface):
            q = first.setdefault(place[p], point_sub[p])
            parent[find(point_sub[p])] = find(q)
        body = np.array([find(s) for s in point_sub])
        _, node, copies = np.unique(np.stack([place, body], axis=1), axis=0,
                                    return_inverse=True, return_counts=True)
        node = node.reshape(-1)
        mean = np.sum(norms / copies[node]) / copies.size
        check(math.isclose(mean, disp["mean_norm"], rel_tol=1e-11),
              f"{name}: mean |u| over distinct nodes {mean} against the report's "
              f"{disp['mean_norm']}")
        # Copies away from contact interfaces agree up to the equality residual.
        spread = np.zeros(copies.size)
        lo = np.full((copies.size, u.shape[1]), np.inf)
        hi = np.full((copies.size, u.shape[1]), -np.inf)
        keep = ~interface
        np.minimum.at(lo, node[keep], u[keep])
        np.maximum.at(hi, node[keep], u[keep])
        multi = np.isfinite(lo[:, 0]) & (copies > 1)
        spread = (hi - lo)[multi].max() if multi.any() else 0.0
        bound = 2 * r["kkt"]["equality_residual"] + 1e-13 * disp["max_norm"]
        check(multi.any() and spread <= bound,
              f"{name}: copies differ by {spread}, more than {bound}")
        for cell_array, count in (("subdomain", r["subdomains"]), ("cluster", r["clusters"]),
                                  ("rank", r["ranks"])):
            a = array(grid, "cell", cell_array)
            check(a is not None and a.size == n_cells and
                  np.array_equal(np.unique(a), np.arange(count)),
                  f"{name}: cell array {cell_array} does not cover 0..{count - 1}")
        if elastic:
            vm = array(grid, "cell", "von_mises")
            check(vm is not None and np.all(np.isfinite(vm)) and vm.min() >= 0 and vm.max() > 0,
                  f"{name}: von_mises missing or invalid")
        print(f"  {n_points} points, {n_cells} cells, max |u| {norms.max():.6g}, "
              f"copies spread {spread:.2e} (bound {bound:.2e})")


EXAMPLES = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "examples")
CASES = [
    ("poisson2d binary", ["--problem", "poisson2d", "-n", "48", "--subdomains", "4", "-m", "2",
                          "--rtol", "1e-8"], 1),
    ("poisson2d ASCII, p1", ["--problem", "poisson2d", "-n", "32", "--subdomains", "4",
                             "--element", "p1", "--rtol", "1e-8", "--vtu-ascii"], 1),
    ("membranes (contact), 3 ranks", ["--problem", "membranes", "-n", "48", "--subdomains", "4",
                                      "-m", "2", "--rtol", "1e-8"], 3),
    ("cube-obstacle (3D elasticity, contact), 2 ranks",
     ["--problem", "cube-obstacle", "--elements", "8,8,8", "--subdomains", "2,2,2",
      "--rtol", "1e-8"], 2),
    ("plate-with-hole (Gmsh, METIS, 2D elasticity)",
     [os.path.join(EXAMPLES, "plate-with-hole.toml")], 1),
    ("bracket (Gmsh tet4, 3D elasticity), 2 ranks", [os.path.join(EXAMPLES, "bracket.toml")], 2),
    ("friction-block (Tresca friction), 2 ranks", [os.path.join(EXAMPLES, "friction-block.toml")],
     2),
    ("punch-on-block (contact between bodies, 3D), 2 ranks",
     [os.path.join(EXAMPLES, "punch-on-block.toml")], 2),
]



def direct_io_supported(directory):
    try:
        fd = os.open(os.path.join(directory, "probe"), os.O_WRONLY | os.O_CREAT | os.O_DIRECT)
    except OSError:
        return False
    os.close(fd)
    return True


def same_bytes_both_ways(name, args, ranks):
    """--vtu-io direct (whole blocks by direct I/O from each thread's contiguous run of
    subdomains, the partial blocks through the page cache) writes the same bytes as buffered
    writes, on 1 to 3 threads, and says so in the report (where the file system allows it)."""
    print(f"{name}: --vtu-io buffered / direct, htfeti solve {' '.join(args)} ({ranks} ranks)")
    files = {}
    with tempfile.TemporaryDirectory() as d:
        direct_ok = direct_io_supported(d)
        for io, threads in (("buffered", 1), ("direct", 1), ("direct", 2), ("direct", 3)):
            out = os.path.join(d, f"{io}{threads}")
            os.mkdir(out)
            vtu = os.path.join(out, "u.pvtu" if ranks > 1 else "u.vtu")
            report_file = os.path.join(out, "r.json")
            cmd = [HTFETI, "solve", *args, "--report", report_file, "--vtu", vtu, "--vtu-io", io]
            if ranks > 1:
                cmd = [MPIEXEC, "-n", str(ranks), *FLAGS, *cmd]
            env = dict(os.environ, OMP_NUM_THREADS=str(threads))
            done = subprocess.run(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                  text=True)
            if not check(done.returncode == 0, f"{name} {io}: exit {done.returncode}: {done.stderr}"):
                return
            with open(report_file) as f:
                used = json.load(f)["output_io"]
            expected = io if io == "buffered" or direct_ok else "buffered"
            check(used == expected, f"{name} {io}: the report says {used}, expected {expected}")
            files[(io, threads)] = {n: open(os.path.join(out, n), "rb").read()
                                    for n in sorted(os.listdir(out)) if "vtu" in n}
        grid, messages = read(os.path.join(d, "direct2", "u.pvtu" if ranks > 1 else "u.vtu"))
        check(not messages and grid.GetNumberOfPoints() > 0,
              f"{name}: the direct output is not readable: {messages}")
    ref = files[("buffered", 1)]
    size = sum(len(b) for b in ref.values())
    for key, got in files.items():
        check(got == ref, f"{name}: {key[0]} on {key[1]} threads differs from buffered")
    print(f"  {size} bytes, the same in all four runs (direct I/O {'used' if direct_ok else 'refused here'})")


for case in CASES:
    run_case(*case)
# 42 MB: several 1 MiB stages per array and thread, so the two stages of each take turns.
same_bytes_both_ways("poisson2d, 42 MB piece", ["--problem", "poisson2d", "-n", "800",
                                               "--subdomains", "8", "-m", "2", "--rtol", "1e-8"], 1)
same_bytes_both_ways("membranes (contact), 2 ranks",
                     ["--problem", "membranes", "-n", "160", "--subdomains", "8", "-m", "2",
                      "--rtol", "1e-8"], 2)
if failures:
    print(f"{len(failures)} check(s) failed")
    sys.exit(1)
print("all VTU checks passed")
