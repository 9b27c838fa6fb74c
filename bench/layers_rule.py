#!/usr/bin/env python3
"""Where one layer of the layered Dirichlet preconditioner pays, by part size (issue 32): the
problems beyond the METIS cubes of bench/dirichlet_layers.py that the automatic choice for 3D
elasticity would meet, each with the lumped preconditioner, one layer (`--preconditioner
dirichlet --dirichlet-layers 1`, implicit storage) and the automatic settings.

Cases (--cases, default all):
  metis80_64    the cube-obstacle 80^3 in 64 METIS parts, A = 1 (bench/cases/cube80_metis64.toml);
  box40_8       the cube-obstacle 40^3 split into 2^3 equal boxes, A = 1 and A = 20;
  linear40_8    the cube 40^3 clamped at x = 0 under its own weight, no contact, 8 METIS parts
                (bench/cases/cube40_metis64_linear.toml with 8 parts);
  hertz_hex     the strongly graded Hertz block, hex8, 16 METIS parts (bench/hertz_cases.py);
  hertz_tet     the Hertz block meshed with tet4 by a size field, 16 METIS parts.
Per run: the primal unknowns per part (the report's primal_dimension / subdomains), the
preconditioner in effect and its layers, Hessian products, the preconditioner's setup
(thread-seconds) and application (seconds), the factorization and solve phases, the report's
total, and the energy. Times are medians of --repeat runs (1 by default).

Usage: bench/layers_rule.py [--cases ...] [--variants lumped layers1 auto] [--repeat 1]
                            [--threads 2] [--out layers_rule.json]"""
import argparse
import os
import statistics
import tempfile

from common import ROOT, cube_obstacle_file, save, solve
import hertz_cases

CASES = ["metis80_64", "box40_8", "linear40_8", "hertz_hex", "hertz_tet"]
VARIANTS = {"lumped": ["--preconditioner", "lumped"],
            "layers1": ["--preconditioner", "dirichlet", "--dirichlet-storage", "implicit",
                        "--dirichlet-layers", "1"],
            "auto": []}
p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--cases", nargs="+", default=CASES, choices=CASES)
p.add_argument("--variants", nargs="+", default=["lumped", "layers1"], choices=sorted(VARIANTS))
p.add_argument("--repeat", type=int, default=1)
p.add_argument("--threads", type=int, default=2)
p.add_argument("--out", default="layers_rule.json")
a = p.parse_args()


def row_of(r):
    t = r["timings"]
    return {"unknowns_per_part": r["primal_dimension"] / r["subdomains"],
            "preconditioner": r.get("preconditioner"),
            "preconditioner_reason": r.get("preconditioner_reason"),
            "layers": r.get("preconditioner_layers"), "products": r["matvecs"],
            "setup_thread_s": t.get("preconditioner_setup", 0.0),
            "apply_s": t.get("preconditioner", 0.0), "factorization_s": t["factorization"],
            "solve_s": t["solve"], "total_s": t["total"], "energy": r["objective"]}


rows = []
with tempfile.TemporaryDirectory() as d:
    files = {"metis80_64": [("A = 1", os.path.join(ROOT, "bench", "cases",
                                                   "cube80_metis64.toml"))],
             "box40_8": [(f"A = {amp:g}", cube_obstacle_file(d, 40, amp, "[2, 2, 2]"))
                         for amp in (1.0, 20.0)]}
    with open(os.path.join(ROOT, "bench", "cases", "cube40_metis64_linear.toml")) as f:
        text = f.read().replace("subdomains = 64", "subdomains = 8")
    linear = os.path.join(d, "linear40_8.toml")
    with open(linear, "w") as f:
        f.write(text)
    files["linear40_8"] = [("", linear)]
    if "hertz_hex" in a.cases or "hertz_tet" in a.cases:
        hz = os.path.join(d, "hz")
        os.makedirs(hz)
        problems = hertz_cases.contact_problems(hz)
        files["hertz_hex"] = [("strong", problems[0][1])]
        files["hertz_tet"] = [("size field", problems[3][1])]
    for case in a.cases:
        for label, path in files[case]:
            for variant in a.variants:
                runs = [row_of(solve([path, *VARIANTS[variant]], threads=a.threads))
                        for _ in range(a.repeat)]
                r = dict(runs[0], case=case, label=label, variant=variant)
                for k in ["setup_thread_s", "apply_s", "factorization_s", "solve_s", "total_s"]:
                    r[k] = statistics.median(x[k] for x in runs)
                rows.append(r)
                print(f"{case} {label} {variant}: {r['unknowns_per_part']:.0f} unknowns per part, "
                      f"{r['preconditioner']} ({r['layers']}), {r['products']} products, setup "
                      f"{r['setup_thread_s']:.2f} thread-s, M^-1 {r['apply_s']:.2f} s, "
                      f"factorization {r['factorization_s']:.2f} s, solve {r['solve_s']:.2f} s, "
                      f"total {r['total_s']:.2f} s", flush=True)

save(a.out, {"repeat": a.repeat, "threads": a.threads, "rows": rows})
