#!/usr/bin/env python3
"""MPRGP's expansion steps (--mprgp-expansion gradient, preconditioned, projected-cg) side by side:
Hessian products, expansion steps and the steps that raised the cost (undone for projected-cg),
on the contact examples,
the sphere-on-block meshed finer (h = 0.01, needs the gmsh program) and the cube-obstacle split
by METIS with A = 20 at 20^3 (8 parts) and 30^3 (27 parts). Counts only (1 rank x 2 threads);
the 40^3 and 80^3 cubes are in bench/cube_obstacle_peer.py.

Usage: bench/mprgp_expansion.py [--out mprgp_expansion.json] [--variants gradient preconditioned
                                  projected-cg] [--large (adds the 40^3 cube, 64 parts, A = 20)]
Writes bench/results/OUT and prints a markdown table."""
import argparse
import os
import subprocess
import tempfile

from common import ROOT, save, solve

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--out", default="mprgp_expansion.json")
p.add_argument("--variants", nargs="+", default=["gradient", "preconditioned", "projected-cg"])
p.add_argument("--large", action="store_true")
a = p.parse_args()

EX = os.path.join(ROOT, "examples")
CUBE = os.path.join(ROOT, "bench", "cases", "cube40_metis64.toml")


def cube(tmp, n, parts):
    with open(CUBE) as f:
        text = f.read()
    text = text.replace("elements = [40, 40, 40]", f"elements = [{n}, {n}, {n}]")
    text = text.replace("subdomains = 64", f"subdomains = {parts}")
    text = text.replace('gap = "sin(pi*x/50)"', 'gap = "20*sin(pi*x/50)"')
    path = os.path.join(tmp, f"cube{n}_metis{parts}_a20.toml")
    with open(path, "w") as f:
        f.write(text)
    return path


def sphere(tmp, h):
    msh = os.path.join(tmp, f"sphere-{h}.msh")
    subprocess.run(["gmsh", os.path.join(EX, "meshes", "sphere-on-block.geo"), "-3", "-setnumber",
                    "h", str(h), "-format", "msh41", "-o", msh], check=True,
                   stdout=subprocess.DEVNULL)
    with open(os.path.join(EX, "sphere-on-block.toml")) as f:
        text = f.read().replace("meshes/sphere-on-block.msh", msh)
    path = os.path.join(tmp, f"sphere-on-block-{h}.toml")
    with open(path, "w") as f:
        f.write(text)
    return path


rows = []
print("| case | " + " | ".join(f"{e}: products (expansion steps, cost increases)"
                             for e in a.variants) + " |")
print("|---|" + "---|" * len(a.variants))
with tempfile.TemporaryDirectory() as tmp:
    cases = [(name, os.path.join(EX, name + ".toml")) for name in (
        "cube-obstacle", "sphere-on-block", "punch-on-block", "cylinder-on-block",
        "membranes-coercive", "membranes-two-bodies", "friction-block")]
    cases += [("sphere-on-block, h = 0.01", sphere(tmp, 0.01)),
              ("cube-obstacle 20^3, METIS 8, A = 20", cube(tmp, 20, 8)),
              ("cube-obstacle 30^3, METIS 27, A = 20", cube(tmp, 30, 27))]
    if a.large:
        cases += [("cube-obstacle 40^3, METIS 64, A = 20", cube(tmp, 40, 64))]
    for name, path in cases:
        row = {"case": name}
        for e in a.variants:
            r = solve([path, "--mprgp-expansion", e], threads=2)
            s = r["solver"]
            row[e] = {"products": r["matvecs"], "outer": r["outer_iterations"],
                      "expansion_steps": s["expansion_steps"],
                      "expansion_cost_increases": s["expansion_cost_increases"],
                      "energy": r["objective"], "converged": r["converged"]}
        rows.append(row)
        print(f"| {name} | " + " | ".join(
            f"{row[e]['products']} ({row[e]['expansion_steps']}, "
            f"{row[e]['expansion_cost_increases']})" for e in a.variants) + " |", flush=True)
print("written:", save(a.out, {"rows": rows}))
