#!/usr/bin/env python3
"""Graded meshes of a Hertz indentation (issue 32): the block [0, 1] x [0, 1] x [-1, 0], a
quarter model (rollers on x = 0 and y = 0, clamped bottom), E = 1000, nu = 0.3, refined toward
the origin of its top face, pressed by a rigid sphere of radius R = 1 by d = 0.01 (the obstacle
u_z <= 0.99 - sqrt(1 - x^2 - y^2); Hertz: contact radius sqrt(R d) = 0.1, force on the quarter
F / 4 = E* R^(1/2) d^(3/2) / 3, E* = E / (1 - nu^2)), and the same block under a uniform
traction on the top (linear: PCG). Meshes: bench/graded_block_hex.geo (structured hex8, 32 cells
per side, first cell hmin = 0.005 (strong grading), 0.015 (mild) and 1/32 (uniform)) and
bench/graded_block_tet.geo (tet4 from a size field, h = 0.004 to H = 0.07). 16 METIS parts,
TFETI, the automatic settings otherwise, rtol 1e-4. Each case split with
`--partition-objective volume`, `area` and the default `auto` (which says what it took and the
share of stretched cells). Per run: PCG iterations or Hessian products (+ the norm estimate's),
outer iterations, the seconds (medians of --repeat runs), and the contact force against Hertz.

Usage: bench/graded_hertz.py [--repeat 3] [--threads 2] [--extra "--preconditioner none"]
                             [--mesh strong] [--objectives volume,area,auto]
                             [--out graded_hertz.json]   (needs the gmsh program)
Writes bench/results/OUT and prints the table."""
import argparse
import math
import os
import statistics
import subprocess
import tempfile

from common import ROOT, machine, save, solve
from hertz_cases import COMMON, CONTACT, MESHES

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--repeat", type=int, default=3)
p.add_argument("--threads", type=int, default=2)
p.add_argument("--extra", default="", help="more htfeti options for every run")
p.add_argument("--mesh", default="", help="only the meshes whose label contains this")
p.add_argument("--objectives", default="volume,area,auto")
p.add_argument("--out", default="graded_hertz.json")
a = p.parse_args()

E, NU, R, D = 1000.0, 0.3, 1.0, 0.01
HERTZ_QUARTER = E / (1 - NU * NU) * math.sqrt(R) * D ** 1.5 / 3
LINEAR = """[[load]]
group = "top"
traction = [0.0, 0.0, -1.0]
"""

rows = []
with tempfile.TemporaryDirectory() as tmp:
    for label, geo, args in [m for m in MESHES if a.mesh in m[0]]:
        msh = os.path.join(tmp, f"m{len(rows)}.msh")
        subprocess.run(["gmsh", os.path.join(ROOT, "bench", geo), "-3", *args, "-format", "msh41",
                        "-o", msh], check=True, stdout=subprocess.DEVNULL)
        for problem, extra in (("linear", LINEAR), ("contact", CONTACT)):
            toml = os.path.join(tmp, f"{problem}.toml")
            with open(toml, "w") as f:
                f.write(COMMON.format(msh=msh) + extra)
            for objective in a.objectives.split(","):
                runs = [solve([toml, "--partition-objective", objective, *a.extra.split()],
                              threads=a.threads) for _ in range(a.repeat)]
                r = runs[0]
                row = {"mesh": label, "problem": problem, "objective": objective,
                       "objective_used": r["partition_objective"],
                       "stretched_cells": r.get("stretched_cells"),
                       "primal": r["primal_dimension"], "dual": r["dual_dimension"],
                       "preconditioner": r["preconditioner"],
                       "solve_s": statistics.median(x["timings"]["solve"] for x in runs),
                       "total_s": statistics.median(x["wall_seconds"] for x in runs),
                       "energy": r["objective"]}
                if problem == "linear":
                    row["pcg_iterations"] = r["matvecs"]
                else:
                    row.update(products=r["matvecs"],
                               norm_estimate_products=r["solver"].get("norm_estimate_matvecs", 0),
                               outer=r["outer_iterations"])
                    force = r["contact_summary"][0]["normal_force"]
                    row.update(normal_force=force, hertz_force=HERTZ_QUARTER,
                               force_error=force / HERTZ_QUARTER - 1)
                rows.append(row)
                print(f"{label:36s} {problem:8s} {objective:6s}->{row['objective_used']:6s} "
                      f"{row.get('pcg_iterations', row.get('products')):5d} "
                      f"solve {row['solve_s']:6.2f} s", flush=True)
save(a.out, {"threads": a.threads, "repeat": a.repeat, "extra": a.extra, "rows": rows,
             "machine": machine()})
