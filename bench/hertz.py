#!/usr/bin/env python3
"""Hertz contact between two elastic bodies under mesh refinement: the plane-strain cylinder on
a block (examples/cylinder-on-block.toml, half model) and the sphere on a block
(examples/sphere-on-block.toml, quarter model), with the meshes of their .geo files made finer
(gmsh -setnumber h ...). Each run's contact pressures (the report's `contact` arrays) are
fitted by least squares to Hertz's profile p^2 = p0^2 (1 - r^2 / a^2) over the nodes in
contact, and the fitted half-width b (2D) or radius a (3D) and peak pressure p0 are compared
with Hertz's formulas for identical materials, E* = E / (2 (1 - nu^2)):
  2D: b^2 = 4 P R / (pi E*), p0 = 2 P / (pi b), P the force per unit length on the cylinder;
  3D: a^3 = 3 F R / (4 E*), p0 = 3 F / (2 pi a^2), F the force on the sphere;
P and F are the loads as meshed (the report's load_resultant, times 2 and 4 for the symmetry).

Usage: bench/hertz.py [--dims 2,3] [--out hertz.json]   (needs the gmsh program)
Writes bench/results/OUT."""
import argparse
import math
import os
import re
import subprocess
import tempfile

from common import ROOT, machine, save, solve

E, NU, R = 1000.0, 0.3, 1.0
E_STAR = E / (2 * (1 - NU * NU))
CASES = {
    2: ("cylinder-on-block", [0.04, 0.02, 0.01, 0.005, 0.0025], 2),
    3: ("sphere-on-block", [0.04, 0.03, 0.02, 0.015, 0.01, 0.007], 3),
}


def fit(r2, p):
    """Least squares of p^2 = A - B r^2; returns (p0, radius)."""
    n = len(r2)
    sx, sy = sum(r2), sum(q * q for q in p)
    sxx, sxy = sum(x * x for x in r2), sum(x * q * q for x, q in zip(r2, p))
    slope = (n * sxy - sx * sy) / (n * sxx - sx * sx)
    A = (sy - slope * sx) / n
    return math.sqrt(A), math.sqrt(A / -slope)


def run(dim, h, tmp):
    name, _, procs = CASES[dim]
    geo = os.path.join(ROOT, "examples", "meshes", name + ".geo")
    msh = os.path.join(tmp, f"{name}-{h}.msh")
    subprocess.run(["gmsh", geo, f"-{dim}", "-setnumber", "h", str(h), "-format", "msh41", "-o",
                    msh], check=True, stdout=subprocess.DEVNULL)
    with open(os.path.join(ROOT, "examples", name + ".toml")) as f:
        text = f.read()
    text = re.sub(r'file = "meshes/[^"]+"', f'file = "{msh}"', text)
    text = re.sub(r"\[output\][^\[]*", "", text)
    toml = os.path.join(tmp, f"{name}-{h}.toml")
    with open(toml, "w") as f:
        f.write(text)
    r = solve([toml], threads=2)
    c = r["contact"]
    load = abs(r["load_resultant"][dim - 1]) * (2 if dim == 2 else 4)
    if dim == 2:
        b = math.sqrt(4 * load * R / (math.pi * E_STAR))
        p0 = 2 * load / (math.pi * b)
        pts = [(x * x, p) for x, p in zip(c["x"], c["pressure"]) if p is not None and p > 0]
    else:
        b = (3 * load * R / (4 * E_STAR)) ** (1 / 3)
        p0 = 3 * load / (2 * math.pi * b * b)
        pts = [(x * x + y * y, p)
               for x, y, p in zip(c["x"], c["y"], c["pressure"]) if p is not None and p > 0]
    fp0, fb = fit([q[0] for q in pts], [q[1] for q in pts])
    return {"dim": dim, "h": h, "primal": r["primal_dimension"], "contact_rows": r["inequalities"],
            "nodes_in_contact": len(pts), "products": r["matvecs"],
            "outer": r["outer_iterations"], "seconds": r["timings"]["total"], "load": load,
            "radius_hertz": b, "radius_fit": fb, "radius_error": fb / b - 1,
            "p0_hertz": p0, "p0_fit": fp0, "p0_error": fp0 / p0 - 1}


p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--dims", default="2,3")
p.add_argument("--out", default="hertz.json")
a = p.parse_args()
rows = []
print("| dim | h | primal | nodes in contact | products | b or a: Hertz / fit (error) | "
      "p0: Hertz / fit (error) | s |")
print("|---|---:|---:|---:|---:|---|---|---:|")
with tempfile.TemporaryDirectory() as tmp:
    for dim in map(int, a.dims.split(",")):
        for h in CASES[dim][1]:
            r = run(dim, h, tmp)
            rows.append(r)
            print(f"| {dim}D | {h} | {r['primal']} | {r['nodes_in_contact']} | {r['products']} | "
                  f"{r['radius_hertz']:.4f} / {r['radius_fit']:.4f} ({100 * r['radius_error']:+.1f}%)"
                  f" | {r['p0_hertz']:.2f} / {r['p0_fit']:.2f} ({100 * r['p0_error']:+.1f}%) | "
                  f"{r['seconds']:.1f} |", flush=True)
print(save(a.out, {"command": "bench/hertz.py", "machine": machine(), "rows": rows}))
