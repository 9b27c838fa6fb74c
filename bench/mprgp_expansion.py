#!/usr/bin/env python3
"""MPRGP's expansion steps (--mprgp-expansion gradient, preconditioned, projected-cg, auto) side
by side: Hessian products, expansion steps and the steps that raised the cost (undone for
projected-cg and auto), on the contact examples, the sphere-on-block meshed finer (h = 0.01, needs
the gmsh program) and the cube-obstacle split by METIS with A = 20 at 20^3 (8 parts) and 30^3
(27 parts). Counts only (1 rank x 2 threads); the 40^3 and 80^3 cubes beside the PETSc peer are
in bench/cube_obstacle_peer.py.

Usage: bench/mprgp_expansion.py [--out mprgp_expansion.json] [--variants gradient preconditioned
                                  projected-cg auto] [--large] [--hertz]
  --large: adds the 40^3 cube at A = 20 split by METIS into 64 parts, the same in clusters of 8
           (H-TFETI-DP) and the same cube split as a box into 4 x 4 x 4
  --hertz: adds the four graded Hertz blocks of bench/graded_hertz.py (bench/hertz_cases.py)
Writes bench/results/OUT and prints a markdown table."""
import argparse
import os
import subprocess
import tempfile

from common import ROOT, machine, save, solve
from hertz_cases import contact_problems

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--out", default="mprgp_expansion.json")
p.add_argument("--variants", nargs="+",
               default=["gradient", "preconditioned", "projected-cg", "auto"])
p.add_argument("--large", action="store_true")
p.add_argument("--hertz", action="store_true")
a = p.parse_args()

EX = os.path.join(ROOT, "examples")
CUBE = os.path.join(ROOT, "bench", "cases", "cube40_metis64.toml")


def cube(tmp, n, parts, box=False):
    """The cube-obstacle n^3 at A = 20 in `parts` METIS parts, or (box) in (n/10)^3 boxes."""
    with open(CUBE) as f:
        text = f.read()
    text = text.replace("elements = [40, 40, 40]", f"elements = [{n}, {n}, {n}]")
    split = f"[{n // 10}, {n // 10}, {n // 10}]" if box else str(parts)
    text = text.replace("subdomains = 64", f"subdomains = {split}")
    text = text.replace('gap = "sin(pi*x/50)"', 'gap = "20*sin(pi*x/50)"')
    path = os.path.join(tmp, f"cube{n}_{'box' if box else 'metis'}{parts}_a20.toml")
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
    cases = [(name, [os.path.join(EX, name + ".toml")]) for name in (
        "cube-obstacle", "sphere-on-block", "punch-on-block", "cylinder-on-block",
        "membranes-coercive", "membranes-two-bodies", "friction-block")]
    cases += [("sphere-on-block, h = 0.01", [sphere(tmp, 0.01)]),
              ("cube-obstacle 20^3, METIS 8, A = 20", [cube(tmp, 20, 8)]),
              ("cube-obstacle 30^3, METIS 27, A = 20", [cube(tmp, 30, 27)])]
    if a.large:
        cases += [("cube-obstacle 40^3, METIS 64, A = 20", [cube(tmp, 40, 64)]),
                  ("cube-obstacle 40^3, METIS 64 in clusters of 8, A = 20",
                   [cube(tmp, 40, 64), "--cluster-size", "8"]),
                  ("cube-obstacle 40^3, box 4 x 4 x 4, A = 20", [cube(tmp, 40, 64, box=True)])]
    if a.hertz:
        cases += [(label, [path]) for label, path in contact_problems(tmp)]
    for name, args in cases:
        row = {"case": name}
        for e in a.variants:
            r = solve([*args, "--mprgp-expansion", e], threads=2)
            s = r["solver"]
            row[e] = {"products": r["matvecs"], "outer": r["outer_iterations"],
                      "expansion_steps": s["expansion_steps"],
                      "expansion_cost_increases": s["expansion_cost_increases"],
                      "projected_cg_expansions": s.get("projected_cg_expansions"),
                      "accuracy_refinements": len(s.get("accuracy_refinements", [])),
                      "energy": r["objective"], "converged": r["converged"]}
        rows.append(row)
        print(f"| {name} | " + " | ".join(
            f"{row[e]['products']} ({row[e]['expansion_steps']}, "
            f"{row[e]['expansion_cost_increases']})" for e in a.variants) + " |", flush=True)
print("written:", save(a.out, {"command": "bench/mprgp_expansion.py " + " ".join(
    ["--variants", *a.variants] + (["--large"] if a.large else []) + (["--hertz"] if a.hertz else [])),
    "rows": rows, "machine": machine()}))
