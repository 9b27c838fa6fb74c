#!/usr/bin/python3
"""Which subdomain sets ||PFP|| on a split of a generated hex8 box: the softest part, found from
the mesh alone, beside the solver's norm estimate and products.

For each METIS seed (and the box split with --box), htfeti solves the problem file with
--partition-seed S and writes its VTU (cell field `subdomain`) and report. This script then
assembles every part's own stiffness matrix K_i with numpy (hex8, 2 x 2 x 2 Gauss points,
E and nu of the problem file: an assembly independent of htfeti's), forms the Schur complement
S_i of K_i on the dofs that rows of B touch (the nodes the part shares with others, the
Dirichlet faces' dofs and the normal dof on the contact face) and takes its smallest nonzero
eigenvalue (each part floats: S_i has the six rigid body motions as its kernel). 1 / that
eigenvalue is the part's softest mode on its interface: the largest eigenvalue of
B_i K_i^+ B_i^T up to the rows' weights (a row shared by two parts weighs 1/sqrt(2) on each).

Only generated boxes ([mesh] generator = "box", hex8) with Dirichlet and contact groups among
x0, x1, y0, y1, z0, z1 and a contact direction along an axis. About 2-4 s per part (dense
linear algebra on about 2,400 interface dofs for parts of 1,000 cells).

Needs numpy and VTK's Python modules: Debian's python3 (/usr/bin/python3) with python3-numpy and
python3-vtk9, which scripts/setup.sh installs.

Usage: /usr/bin/python3 bench/part_softness.py [--case cases/cube40_metis64_a20.toml] [--seeds 1 2 3 4] [--box]
                              [--out part_softness.json]
Writes bench/results/OUT and prints one line per split."""
import argparse
import json
import os
import subprocess
import tempfile
import tomllib

import numpy as np
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader

from common import BIN, ROOT, env, save

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--case", default="cases/cube40_metis64_a20.toml")
p.add_argument("--seeds", type=int, nargs="*", default=[1, 2, 3, 4])
p.add_argument("--box", action="store_true", help="also the box split (subdomains s x s x s)")
p.add_argument("--threads", type=int, default=2)
p.add_argument("--out", default="part_softness.json")
a = p.parse_args()

case = a.case if os.path.isabs(a.case) else os.path.join(ROOT, "bench", a.case)
with open(case, "rb") as f:
    prob = tomllib.load(f)
mesh = prob["mesh"]
if mesh.get("generator") != "box" or mesh.get("element", "hex8") != "hex8":
    raise SystemExit("part_softness.py: only generated hex8 boxes")
size = np.array(mesh["size"], float)
cells_per_side = np.array(mesh["elements"], int)
E, nu = prob["physics"]["young"], prob["physics"]["poisson"]
FACES = {"x0": (0, 0.0), "x1": (0, 1.0), "y0": (1, 0.0), "y1": (1, 1.0), "z0": (2, 0.0), "z1": (2, 1.0)}


def on_face(xyz, group):
    axis, side = FACES[group]
    return np.abs(xyz[:, axis] - side * size[axis]) <= 1e-9 * size.max()


# hex8 reference nodes (VTK order) and the element stiffness of a cell given its 8 corners.
XI = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
               [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], float)
lam_, mu_ = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
D = np.zeros((6, 6))
D[:3, :3] = lam_
D[np.arange(3), np.arange(3)] += 2 * mu_
D[3:, 3:] = np.eye(3) * mu_
GAUSS = [np.array([a_, b_, c_]) / np.sqrt(3) for a_ in (-1, 1) for b_ in (-1, 1) for c_ in (-1, 1)]
DN_REF = []  # dN/dxi at each Gauss point, 8 x 3
for gp in GAUSS:
    dn = np.empty((8, 3))
    for k in range(8):
        for d in range(3):
            dn[k, d] = XI[k, d] * np.prod([1 + XI[k, e] * gp[e] for e in range(3) if e != d]) / 8
    DN_REF.append(dn)


def element_matrix(x):
    ke = np.zeros((24, 24))
    for dn in DN_REF:
        J = dn.T @ x  # 3 x 3
        dN = dn @ np.linalg.inv(J).T  # 8 x 3, d/dx
        B = np.zeros((6, 24))
        B[0, 0::3], B[1, 1::3], B[2, 2::3] = dN[:, 0], dN[:, 1], dN[:, 2]
        B[3, 0::3], B[3, 1::3] = dN[:, 1], dN[:, 0]
        B[4, 1::3], B[4, 2::3] = dN[:, 2], dN[:, 1]
        B[5, 0::3], B[5, 2::3] = dN[:, 2], dN[:, 0]
        ke += B.T @ D @ B * np.linalg.det(J)
    return ke


def read_split(vtu):
    r = vtkXMLUnstructuredGridReader()
    r.SetFileName(vtu)
    r.Update()
    g = r.GetOutput()
    sub = vtk_to_numpy(g.GetCellData().GetArray("subdomain")).astype(int)
    conn = vtk_to_numpy(g.GetCells().GetConnectivityArray()).reshape(-1, 8)
    pts = vtk_to_numpy(g.GetPoints().GetData()).astype(float)
    # The VTU holds every subdomain's own copy of its nodes: merge them by grid position.
    h = size / cells_per_side
    ijk = np.rint(pts / h).astype(np.int64)
    key = (ijk[:, 0] * (cells_per_side[1] + 1) + ijk[:, 1]) * (cells_per_side[2] + 1) + ijk[:, 2]
    uniq, inverse = np.unique(key, return_inverse=True)
    xyz = np.zeros((len(uniq), 3))
    xyz[inverse] = pts
    return sub, inverse[conn], xyz


def softest_modes(sub, conn, xyz):
    """Per part: 1 / the smallest nonzero eigenvalue of its interface Schur complement."""
    nparts = sub.max() + 1
    parts_of_node = np.zeros(len(xyz), int)
    for q in range(nparts):
        parts_of_node[np.unique(conn[sub == q])] += 1
    fixed = np.zeros((len(xyz), 3), bool)  # dofs that rows of B touch besides the gluing
    for d in prob.get("dirichlet", []):
        comps = d.get("components", ["x", "y", "z"])
        for c in comps:
            fixed[on_face(xyz, d["group"]), "xyz".index(c)] = True
    for c in prob.get("contact", []):
        direction = np.abs(np.array(c["direction"], float))
        fixed[on_face(xyz, c["group"]), int(np.argmax(direction))] = True
    soft = []
    for q in range(nparts):
        cells = np.where(sub == q)[0]
        nodes = np.unique(conn[cells])
        local = -np.ones(len(xyz), int)
        local[nodes] = np.arange(len(nodes))
        n = 3 * len(nodes)
        K = np.zeros((n, n))
        for c in cells:
            idx = (3 * local[conn[c]][:, None] + np.arange(3)).ravel()
            K[np.ix_(idx, idx)] += element_matrix(xyz[conn[c]])
        touched = fixed[nodes].copy()
        touched[parts_of_node[nodes] > 1] = True
        b = np.flatnonzero(touched.ravel())
        i = np.flatnonzero(~touched.ravel())
        S = K[np.ix_(b, b)] - K[np.ix_(b, i)] @ np.linalg.solve(K[np.ix_(i, i)], K[np.ix_(i, b)])
        w = np.linalg.eigvalsh(0.5 * (S + S.T))
        nonzero = w[w > 1e-8 * w[-1]]
        soft.append({"part": q, "cells": int(len(cells)), "zero_eigenvalues": int(len(w) - len(nonzero)),
                     "softest": float(1.0 / nonzero[0])})
    return soft


splits = [("box", None)] if a.box else []
splits += [(f"METIS seed {s}", s) for s in a.seeds]
rows = []
with tempfile.TemporaryDirectory() as tmp:
    for name, seed in splits:
        vtu, rep = os.path.join(tmp, "split.vtu"), os.path.join(tmp, "report.json")
        args = [BIN, "solve", case, "--vtu", vtu, "--report", rep]
        if seed is None:
            with open(case) as f:
                text = f.read()
            parts = int(prob["decomposition"]["subdomains"])
            side = round(parts ** (1 / 3))
            if side ** 3 != parts:
                raise SystemExit("part_softness.py --box: subdomains is not a cube")
            box_case = os.path.join(tmp, "box.toml")
            with open(box_case, "w") as f:
                f.write(text.replace(f"subdomains = {parts}", f"subdomains = [{side}, {side}, {side}]"))
            args[2] = box_case
        else:
            args += ["--partition-seed", str(seed)]
        # (common.solve would delete the VTU this script reads; the same environment)
        subprocess.run(args, check=True, stdout=subprocess.DEVNULL, env=env(a.threads))
        with open(rep) as f:
            r = json.load(f)
        soft = softest_modes(*read_split(vtu))
        values = np.array([s["softest"] for s in soft])
        worst = int(np.argmax(values))
        order = np.sort(values)[::-1]
        row = {"split": name, "seed": seed, "products": r["matvecs"],
               "expansion_steps": r["solver"].get("expansion_steps"),
               "expansion_cost_increases": r["solver"].get("expansion_cost_increases"),
               "norm_estimate": r["solver"]["norm_estimate"], "softest_part": worst,
               "softest": float(order[0]), "second": float(order[1]), "median": float(np.median(values)),
               "parts": soft}
        row["norm_over_softest"] = row["norm_estimate"] / row["softest"]
        rows.append(row)
        print(f"{name:16s} products {row['products']:4d}  ||PFP|| {row['norm_estimate']:.3e}  softest part "
              f"{worst} {order[0]:.3e} (next {order[1]:.3e}, median {row['median']:.3e})  "
              f"||PFP|| / softest {row['norm_over_softest']:.2f}", flush=True)
save(a.out, {"case": a.case, "threads": a.threads, "rows": rows})  # (save adds the machine)
