#!/usr/bin/env python3
"""Where SMALBE-M spends its Hessian products, outer iteration by outer iteration: runs htfeti
solve on each case and prints the report's solver.outer_log (per outer iteration of every solve:
the inner solve's MPRGP steps by kind, the products it took, ||g^P||/||b|| and
||PFP|| ||G lambda||/||b|| where it ended, M and rho), then per case the products by kind of
step: CG and proportioning steps take one product each, expansion steps two (the CG direction's
product, then the gradient at the expanded point) and three where a projected CG step was tried
and undone (with --mprgp-expansion preconditioned three, the third counted under "other");
face solves one per face iteration; the norm estimate's and the accuracy refinements' are in
the totals. Counts do not depend on the machine's speed.

Cases (--cases, default all): the 40^3 cube-obstacle at A = 20 split by METIS into 64 parts and
as a 4 x 4 x 4 box (bench/cases/cube40_metis64_a20.toml), the strongly graded Hertz block of
bench/hertz_cases.py (needs gmsh), and with --large the 80^3 cube at A = 20 split by METIS
(bench/cases/cube80_metis512_a20.toml, about 80 s).

Usage: bench/smalbe_path.py [--cases metis40 box40 hertz] [--large] [--threads 2]
                            [--extra "htfeti options"] [--out smalbe_path.json]
Writes bench/results/OUT."""
import argparse
import os
import shlex
import tempfile

from common import ROOT, machine, save, solve
from hertz_cases import contact_problems

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--cases", nargs="+", default=["metis40", "box40", "hertz"])
p.add_argument("--large", action="store_true", help="also the 80^3 cube in 512 METIS parts")
p.add_argument("--threads", type=int, default=2)
p.add_argument("--extra", default="", help="more htfeti options for every run")
p.add_argument("--out", default="smalbe_path.json")
a = p.parse_args()

cases = os.path.join(ROOT, "bench", "cases")
tmp = tempfile.TemporaryDirectory()  # removed at exit
box40 = os.path.join(tmp.name, "cube40_box_a20.toml")
with open(os.path.join(cases, "cube40_metis64_a20.toml")) as f, open(box40, "w") as g:
    g.write(f.read().replace("subdomains = 64", "subdomains = [4, 4, 4]"))
CASES = {"metis40": ("cube-obstacle 40^3 A = 20, METIS 64",
                     os.path.join(cases, "cube40_metis64_a20.toml")),
         "box40": ("cube-obstacle 40^3 A = 20, box 4 x 4 x 4", box40)}
if "hertz" in a.cases:
    CASES["hertz"] = ("Hertz hex8, strong grading (hmin 0.005)", contact_problems(tmp.name)[0][1])
names = list(a.cases) + (["metis80"] if a.large else [])
CASES["metis80"] = ("cube-obstacle 80^3 A = 20, METIS 512",
                    os.path.join(cases, "cube80_metis512_a20.toml"))

rows = []
for key in names:
    label, path = CASES[key]
    r = solve([path, *shlex.split(a.extra)], threads=a.threads)
    s = r["solver"]
    log = s.get("outer_log", [])
    print(f"\n{label}: {r['matvecs']} products (+{s.get('norm_estimate_matvecs', 0)} for the "
          f"norm estimate), {r['outer_iterations']} outer iterations")
    print("| solve | outer | MPRGP its | CG | expansion | proportioning | products | "
          "\u2016g^P\u2016/\u2016b\u2016 | \u2016PFP\u2016 \u2016G\u03bb\u2016/\u2016b\u2016 |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    before = 0
    for o in log:
        print(f"| {o['solve']} | {o['outer']} | {o['inner_iterations']} | {o['cg_steps']} | "
              f"{o['expansion_steps']} | {o['proportioning_steps']} | "
              f"{o['products'] - before} | {o['projected_gradient']:.1e} | {o['equality']:.1e} |")
        before = o["products"]
    cg = s.get("cg_steps", 0) + s.get("proportioning_steps", 0)
    expansion = 2 * s.get("expansion_steps", 0) + s.get("expansion_cost_increases", 0)
    face = s.get("face_iterations", 0)
    rest = r["matvecs"] - cg - expansion - face
    by_kind = {"cg_and_proportioning": cg, "expansion": expansion, "face": face,
               "other": rest}
    print("products by kind of step: " + ", ".join(f"{k} {v}" for k, v in by_kind.items()))
    rows.append({"case": label, "products": r["matvecs"],
                 "norm_estimate_products": s.get("norm_estimate_matvecs", 0),
                 "outer_iterations": r["outer_iterations"], "products_by_kind": by_kind,
                 "energy": r["objective"], "solver": s})
print("\nwritten:", save(a.out, {"threads": a.threads, "extra": a.extra, "rows": rows,
                                 "machine": machine()}))
