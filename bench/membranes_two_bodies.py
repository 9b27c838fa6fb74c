#!/usr/bin/env python3
"""The paper's two membranes posed as two bodies of a Gmsh mesh with non-matching meshes on the
contact line (examples/membranes-two-bodies.toml: n1 x n1 and n2 x n2 quad4, mortar rows)
against the built-in problem (matching grids, node-to-node rows) under refinement: both
energies tend to the same limit, estimated by the built-in problem at n = 1024.

Usage: bench/membranes_two_bodies.py [--out membranes_two_bodies.json]   (needs gmsh)
Writes bench/results/OUT."""
import argparse
import os
import re
import subprocess
import tempfile

from common import ROOT, save, solve

LEVELS = [(12, 16), (24, 32), (48, 64), (96, 128), (192, 256), (384, 512)]

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--out", default="membranes_two_bodies.json")
a = p.parse_args()
ref = solve(["--problem", "membranes", "-n", 1024, "--subdomains", 8, "--rtol", 1e-10],
            threads=2)["objective"]
print(f"built-in, n = 1024: energy {ref:.10f}\n")
print("| n1 / n2 | two bodies: energy | - limit | built-in at n = n2: energy | - limit | "
      "products (two bodies) |")
print("|---|---:|---:|---:|---:|---:|")
rows = []
with open(os.path.join(ROOT, "examples", "membranes-two-bodies.toml")) as f:
    example = f.read()
with tempfile.TemporaryDirectory() as tmp:
    for n1, n2 in LEVELS:
        msh = os.path.join(tmp, f"m{n1}.msh")
        subprocess.run(["gmsh", os.path.join(ROOT, "examples", "meshes", "membranes-two-bodies.geo"),
                        "-2", "-setnumber", "n1", str(n1), "-setnumber", "n2", str(n2), "-format",
                        "msh41", "-o", msh], check=True, stdout=subprocess.DEVNULL)
        text = re.sub(r'file = "meshes/[^"]+"', f'file = "{msh}"', example)
        text = re.sub(r"\[output\][^\[]*", "", text)
        toml = os.path.join(tmp, f"m{n1}.toml")
        with open(toml, "w") as f:
            f.write(text)
        two = solve([toml, "--rtol", 1e-10], threads=2)
        built = solve(["--problem", "membranes", "-n", n2, "--subdomains", 8, "--rtol", 1e-10],
                      threads=2)
        e2, eb = two["objective"], built["objective"]
        rows.append({"n1": n1, "n2": n2, "two_bodies": e2, "builtin": eb, "limit": ref,
                     "products": two["matvecs"], "converged": two["converged"]})
        print(f"| {n1} / {n2} | {e2:.10f} | {e2 - ref:.2e} | {eb:.10f} | {eb - ref:.2e} | "
              f"{two['matvecs']} |", flush=True)
print(save(a.out, {"command": "bench/membranes_two_bodies.py", "limit_n1024": ref, "rows": rows}))
