#!/usr/bin/env python3
"""How far the strongly graded Hertz block of issue 32 is from its target of 100 products, and
what moves the count: METIS's seed, the preconditioner, the gap of rows that never touch.

The block is bench/hertz_cases.py's first mesh (structured hex8 graded toward the contact, cells
up to 0.2 x 0.005 x 0.005, 16 METIS parts, TFETI, rtol 1e-4). Runs, all with the automatic
settings except what the row names:
- the contact problem for METIS's seeds (--seeds, default 1-5) with the lumped preconditioner
  (the automatic one) and the Dirichlet one: Hessian products (the norm estimate's apart), the
  gluing residual of the first solve in units of rtol (above 3 the accuracy refinement solves
  on), the energy error against a reference solved to rtol 1e-10;
- the same block under a uniform traction (linear: PCG iterations), seed 1, both
  preconditioners, and the uniform mesh (hmin 1/32) beside it: the dual problem's conditioning
  on the graded mesh against the uniform one;
- the contact problem with the gap set to 100 where x^2 + y^2 > 0.25 (the sphere stays 0.9
  away there; the contact radius is 0.1): the same solution, a larger ||b||.
Counts do not depend on the machine's speed.

Usage: bench/graded_hertz_spread.py [--seeds 1 2 3 4 5] [--threads 2]
                                    [--extra "--face-changes 10"] [--out graded_hertz_spread.json]
--extra: more htfeti options for every run but the reference.
Writes bench/results/OUT."""
import argparse
import os
import shlex
import tempfile

from common import machine, save, solve
from hertz_cases import COMMON, CONTACT, MESHES, contact_problems

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5])
p.add_argument("--threads", type=int, default=2)
p.add_argument("--extra", default="", help="more htfeti options for every run but the reference")
p.add_argument("--out", default="graded_hertz_spread.json")
a = p.parse_args()
extra = shlex.split(a.extra)

LINEAR = '[[load]]\ngroup = "top"\ntraction = [0.0, 0.0, -1.0]\n'
FAR_GAP = 'gap = "x^2 + y^2 > 0.25 ? 100 : 0.99 - sqrt(max(1e-12, 1 - x^2 - y^2))"'


def contact_row(r, reference):
    s = r["solver"]
    refinements = s.get("accuracy_refinements", [])
    return {"products": r["matvecs"], "norm_estimate_products": s.get("norm_estimate_matvecs", 0),
            "outer": r["outer_iterations"],
            "first_gluing_over_rtol": refinements[0]["gluing_residual_over_rtol"]
            if refinements else None,
            "refinements": max(0, len(refinements) - 1), "rhs_norm": s["rhs_norm"],
            "energy": r["objective"],
            "energy_error": abs(r["objective"] / reference - 1) if reference else None,
            "solve_s": r["timings"]["solve"], "total_s": r["wall_seconds"]}


rows = []
with tempfile.TemporaryDirectory() as tmp:
    (label, toml), (_, _), (uniform_label, uniform_toml), _ = contact_problems(tmp)
    ref = solve([toml, "--rtol", "1e-10", "--preconditioner", "dirichlet"], threads=a.threads)
    reference = ref["objective"]
    print(f"reference energy (rtol 1e-10): {reference:.12e}", flush=True)
    for seed in a.seeds:
        for pre in ("lumped", "dirichlet"):
            r = solve([toml, "--partition-seed", seed, "--preconditioner", pre, *extra],
                      threads=a.threads)
            row = {"case": "contact", "mesh": label, "seed": seed, "preconditioner": pre,
                   **contact_row(r, reference)}
            rows.append(row)
            print(f"contact seed {seed} {pre:9s} {row['products']:4d} products "
                  f"(gluing "
                  f"{row['first_gluing_over_rtol']:.3g} rtol), energy error "
                  f"{row['energy_error']:.1e}", flush=True)
    with open(toml) as f:
        text = f.read()
    for case, mesh_toml, mesh_label in (("linear", toml, label),
                                        ("linear", uniform_toml, uniform_label)):
        with open(mesh_toml) as f:
            t = f.read()
        lin = os.path.join(tmp, f"linear_{len(rows)}.toml")
        with open(lin, "w") as f:
            f.write(t[:t.index("[[contact]]")] + LINEAR)
        for pre in ("lumped", "dirichlet"):
            r = solve([lin, "--preconditioner", pre, *extra], threads=a.threads)
            rows.append({"case": case, "mesh": mesh_label, "seed": 1, "preconditioner": pre,
                         "pcg_iterations": r["matvecs"]})
            print(f"linear {mesh_label:36s} {pre:9s} {r['matvecs']:4d} PCG products", flush=True)
    far = os.path.join(tmp, "far.toml")
    with open(far, "w") as f:
        f.write("\n".join(FAR_GAP if line.startswith("gap = ") else line
                          for line in text.splitlines()) + "\n")
    r = solve([far, *extra], threads=a.threads)
    row = {"case": "contact, gap 100 beyond r = 0.5", "mesh": label, "seed": 1,
           "preconditioner": r["preconditioner"], **contact_row(r, reference)}
    rows.append(row)
    print(f"far gap: {row['products']} products, ||b|| {row['rhs_norm']:.4g}, gluing "
          f"{row['first_gluing_over_rtol']:.4g} rtol, {row['refinements']} refinements, energy "
          f"error {row['energy_error']:.1e}", flush=True)
save(a.out, {"threads": a.threads, "extra": a.extra, "reference_energy": reference, "rows": rows,
             "machine": machine()})
