#!/usr/bin/env python3
"""Products and accuracy of SMALBE-M over 26 contact problems (bench/contact_cases.py: those of
bench/smalbe_sweep.py --metis --hertz --friction but the one at rtol 1e-10, and the 40^3
cube-obstacle at A = 20 split by METIS and as a box): per case the Hessian products (+ the
norm estimate's) and the energy. With --reference (the same script run with --rtol 1e-8 on one
build) also each energy's relative distance from the reference's, so that fewer products are
not bought with less accuracy.

Usage: bench/contact_products.py [--rtol R] [--reference REF.json] [--threads 2]
                                 [--extra "htfeti options"] [--out contact_products.json]     (needs the gmsh program)
Writes bench/results/OUT and prints one line per case and the totals."""
import argparse
import json
import os
import shlex
import tempfile

from common import ROOT, machine, save, solve
from contact_cases import case_file, contact_cases

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--rtol", type=float, default=None, help="passed as --rtol (default: the cases')")
p.add_argument("--reference", default=None, help="a results file of this script at rtol 1e-8")
p.add_argument("--threads", type=int, default=2)
p.add_argument("--extra", default="", help="more htfeti options for every case")
p.add_argument("--out", default="contact_products.json")
a = p.parse_args()

tmp = tempfile.TemporaryDirectory()  # removed at exit
# The cases of bench/smalbe_sweep.py --metis --hertz --friction (without the one at its own
# rtol 1e-10), and the 40^3 cube at A = 20 split by METIS and as a 4 x 4 x 4 box.
CASES = contact_cases(tmp.name, metis=True, hertz=True, friction=True, tight=False)
box_a20 = os.path.join(tmp.name, "cube40_box_a20.toml")
with open(case_file("cube40_metis64_a20")) as f, open(box_a20, "w") as g:
    g.write(f.read().replace("subdomains = 64", "subdomains = [4, 4, 4]"))
CASES += [("cube-obstacle 40^3 A = 20, METIS 64", [case_file("cube40_metis64_a20")]),
          ("cube-obstacle 40^3 A = 20, box 4 x 4 x 4", [box_a20])]

ref = None
if a.reference:
    with open(a.reference if os.path.isabs(a.reference)
              else os.path.join(ROOT, "bench", "results", a.reference)) as f:
        ref = {r["case"]: r for r in json.load(f)["rows"]}
rows, total, errors = [], 0, []
for name, args in CASES:
    r = solve([*args, *(["--rtol", a.rtol] if a.rtol else []), *shlex.split(a.extra)],
              threads=a.threads)
    s = r["solver"]
    row = {"case": name, "converged": r["converged"], "outer_iterations": r["outer_iterations"],
           "products": r["matvecs"], "norm_estimate_products": s.get("norm_estimate_matvecs", 0),
           "face_solves": s.get("face_solves", 0), "face_converged": s.get("face_converged", 0),
           "energy": r["objective"], "solve_s": r["timings"]["solve"]}
    if ref and name in ref:
        row["energy_error"] = abs(row["energy"] / ref[name]["energy"] - 1)
        errors.append(row["energy_error"])
    cost = row["products"] + row["norm_estimate_products"]
    total += cost
    rows.append(row)
    print(f"{name:48s} {cost:5d} products"
          + (f"  energy error {row['energy_error']:.1e}" if "energy_error" in row else ""),
          flush=True)
print(f"total {total} products" + (f", largest energy error {max(errors):.1e}" if errors else ""))
save(a.out, {"rtol": a.rtol, "threads": a.threads, "reference": a.reference, "extra": a.extra,
             "total_products": total, "rows": rows, "machine": machine()})
