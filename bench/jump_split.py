#!/usr/bin/env python3
"""METIS splits of meshes with coefficient jumps, with and without the jump split
(`--partition-jump-ratio`, partition.hpp) and the weighted projector in PCG's preconditioner
(`--pcg-projector`, solver.hpp): the same problem split by METIS so that subdomains may straddle
a jump (ratio 0; the automatic projector is then orthogonal) and so that none does (ratio 10,
the default), with the orthogonal and the automatic projector (and the straddling split with the weighted
one), beside the box split (orthogonal, weighted and automatic). Automatic settings
otherwise (a coefficient field: the Dirichlet preconditioner with stiffness scaling), TFETI,
1 rank.

Cases:
  square_1e4, square_1e6  Laplace on the unit square, 128 x 128 quad4, unit source, u = 0 on
                          x = 0, the half x > 0.5 conducting 1e4 (1e6) times better (the
                          problem of examples/heterogeneous.toml), 64 METIS parts / 8 x 8 boxes,
                          rtol 1e-8;
  cube_1e3, cube_1e6      elasticity, 24^3 hex8 cube [0, 100]^3 clamped at x = 0 under its own
                          weight, the half x > 50 1e3 (1e6) times stiffer, 64 METIS parts /
                          4 x 4 x 4 boxes, rtol 1e-6;
  stiff_ball, soft_ball   the same cube with a ball of radius 30 at its centre 1e3 times stiffer
                          (softer) than the rest, 64 METIS parts (and 4 x 4 x 4 boxes, which
                          the ball cuts through, for the stiff one), rtol 1e-6;
  smooth                  the same cube with the smooth field 1 + x/10 (no jump), 64 METIS
                          parts / 4 x 4 x 4 boxes, rtol 1e-6;
  plate_1e3, plate_1e6    plane strain on the Gmsh plate-with-hole, 16 METIS parts, the part
                          x > 1 1e3 (1e6) times stiffer, rtol 1e-8 (docs/results.md,
                          "Coefficient jumps").
Per run: the stop reason, PCG iterations (products with F), the regions split apart, the
projector used, the energy, the report's total seconds (median of --repeat runs); energies of
the runs that converged against the box split's (automatic) where there is one.

Usage: bench/jump_split.py [--cases ...] [--repeat 1] [--threads 2] [--out jump_split.json]"""
import argparse
import os
import statistics
import tempfile

from common import JUMP_CUBE_TOML, JUMP_PLATE_TOML, ROOT, save, solve

SQUARE = """[mesh]
generator = "box"
size = [1.0, 1.0]
elements = [128, 128]
element = "quad4"
[physics]
type = "laplace"
source = 1.0
coefficient = "x > 0.5 ? {jump} : 1"
[[dirichlet]]
group = "x0"
value = 0.0
[decomposition]
subdomains = {split}
[solver]
rtol = 1e-8
"""

BALL = "(x-50)^2 + (y-50)^2 + (z-50)^2 < 900 ? {c} : 1"
PLATE_MESH = os.path.join(ROOT, "examples", "meshes", "plate-with-hole.msh")


def cube(field, split):
    return JUMP_CUBE_TOML.format(field=field, split=split, rtol="1e-6")


def plate(jump):
    return JUMP_PLATE_TOML.format(coef=f"x > 1 ? {jump} : 1", m=1, mesh=PLATE_MESH)

# name: (METIS text, box text or None)
CASES = {
    "square_1e4": (SQUARE.format(jump="1e4", split="64"), SQUARE.format(jump="1e4", split="[8, 8]")),
    "square_1e6": (SQUARE.format(jump="1e6", split="64"), SQUARE.format(jump="1e6", split="[8, 8]")),
    "cube_1e3": (cube("x > 50 ? 1e3 : 1", "64"), cube("x > 50 ? 1e3 : 1", "[4, 4, 4]")),
    "cube_1e6": (cube("x > 50 ? 1e6 : 1", "64"), cube("x > 50 ? 1e6 : 1", "[4, 4, 4]")),
    "stiff_ball": (cube(BALL.format(c="1e3"), "64"), cube(BALL.format(c="1e3"), "[4, 4, 4]")),
    "smooth": (cube("1 + x/10", "64"), cube("1 + x/10", "[4, 4, 4]")),
    "soft_ball": (cube(BALL.format(c="1e-3"), "64"), None),
    "plate_1e3": (plate("1e3"), None),
    "plate_1e6": (plate("1e6"), None),
}

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
p.add_argument("--repeat", type=int, default=1)
p.add_argument("--threads", type=int, default=2)
p.add_argument("--out", default="jump_split.json")
a = p.parse_args()


def row_of(runs):
    r = runs[0]
    return {"stop_reason": r["stop_reason"], "converged": r["converged"],
            "products": r["matvecs"], "regions": r.get("partition_jump_regions"),
            "declined": r.get("partition_jump_splits_declined"), "energy": r["objective"],
            "projector": r["solver"].get("pcg_projector"),
            "total_s": statistics.median(x["timings"]["total"] for x in runs)}


rows = []
with tempfile.TemporaryDirectory() as d:
    for name in a.cases:
        metis, box = CASES[name]
        path = os.path.join(d, name + ".toml")
        with open(path, "w") as f:
            f.write(metis)
        row = {"case": name}
        runs = [("straddling", path, ["--partition-jump-ratio", "0"]),
                ("straddling_weighted", path,
                 ["--partition-jump-ratio", "0", "--pcg-projector", "weighted"]),
                ("jump_split_orthogonal", path, ["--pcg-projector", "orthogonal"]),
                ("jump_split", path, [])]
        if box:
            bpath = os.path.join(d, name + "_box.toml")
            with open(bpath, "w") as f:
                f.write(box)
            runs += [("box_orthogonal", bpath, ["--pcg-projector", "orthogonal"]),
                     ("box_weighted", bpath, ["--pcg-projector", "weighted"]),
                     ("box", bpath, [])]
        for label, f, extra in runs:
            row[label] = row_of([solve([f, *extra], threads=a.threads) for _ in range(a.repeat)])
        if box:
            for label, _, _ in runs:
                if label != "box" and row[label]["converged"] and row["box"]["converged"]:
                    row[label]["energy_vs_box"] = (abs(row[label]["energy"] - row["box"]["energy"])
                                                   / abs(row["box"]["energy"]))
        rows.append(row)
        cols = [f"{k}: {row[k]['products']} ({row[k]['stop_reason']}, {row[k]['projector']}, "
                f"{row[k]['total_s']:.2f} s)" for k, _, _ in runs]
        print(f"{name:12s} " + " | ".join(cols), flush=True)

save(a.out, {"repeat": a.repeat, "threads": a.threads, "rows": rows})
