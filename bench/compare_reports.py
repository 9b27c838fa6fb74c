#!/usr/bin/env python3
"""Reports of the built-in problems, the examples and the cube-obstacle from two htfeti builds,
side by side: iteration counts, products and the relative energy difference (one rank, one
thread). BEFORE is built from an older commit, as in bench/compare_builds.py. A restructuring
that does not change the arithmetic must give `identical` on every row (energy, counts and KKT
figures bit for bit).

Usage: bench/compare_reports.py --before /tmp/htfeti-before/b/htfeti [--after build/htfeti]
                                [--out compare_reports.json]
Writes bench/results/OUT."""
import argparse
import os

from common import ROOT, save, solve

CASES = [
    "--problem membranes -n 128 --subdomains 8 -m 1",
    "--problem membranes -n 128 --subdomains 8 -m 2",
    "--problem membranes -n 128 --subdomains 8 -m 4 --glue corners",
    "--problem membranes -n 128 --subdomains 8 -m 4 --glue corners+averages",
    "--problem membranes -n 96 --subdomains 8 -m 2 --element p1",
    "--problem membranes-coercive -n 64 --subdomains 8 -m 2",
    "--problem poisson2d -n 64 --subdomains 8 -m 1",
    "--problem poisson2d -n 64 --subdomains 8 -m 4",
    "--problem poisson2d -n 64 --subdomains 8 -m 2 --glue corners --element p1",
    "--problem membranes -n 64 --subdomains 8 -m 2 --dual-operator implicit",
    "--problem membranes -n 512 --subdomains 32 -m 1",
    "--problem membranes -n 512 --subdomains 32 -m 2",
    "--problem membranes -n 512 --subdomains 32 -m 4",
    "--problem membranes -n 512 --subdomains 32 -m 8",
    "--problem membranes -n 128 --subdomains 8 -m 2 --preconditioner dirichlet",
    "--problem membranes -n 128 --subdomains 8 -m 2 --coarse-steps-per-product 1",
    "--problem membranes -n 128 --subdomains 8 -m 2 --norm-estimate lanczos",
    "--problem membranes -n 128 --subdomains 8 -m 2 --explicit-precision single",
    "--problem cube-obstacle",
    "--problem cube-obstacle --obstacle-amplitude 20",
    "--problem cube-obstacle --elements 8,8,8 --subdomains 4,4,4 -m 2",
]
EXAMPLES = ["block3d", "bracket", "cube-obstacle", "heterogeneous", "membranes-coercive",
            "membranes", "plate-with-hole", "poisson2d",
            # contact between bodies (mortar rows) and friction
            "cylinder-on-block", "membranes-two-bodies", "punch-on-block", "sphere-on-block",
            "friction-block", "friction-block-3d"]
CASES += [os.path.join(ROOT, "examples", e + ".toml") for e in EXAMPLES]
KKT = ("equality_residual", "max_violation", "min_multiplier", "complementarity")

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--before", required=True)
p.add_argument("--after", default=os.path.join(ROOT, "build", "htfeti"))
p.add_argument("--out", default="compare_reports.json")
a = p.parse_args()
rows = []
print("| case | outer before/after | matvecs before/after | energy rel. diff | identical |")
print("|---|---|---|---:|---|")
for case in CASES:
    r = {}
    for label, binary in (("before", a.before), ("after", a.after)):
        r[label] = solve(case.split(), binary=binary)
    b, f = r["before"], r["after"]
    diff = abs(b["objective"] - f["objective"]) / abs(b["objective"])
    same = (b["objective"] == f["objective"] and
            all(b[k] == f[k] for k in ("outer_iterations", "inner_iterations", "matvecs")) and
            all(b["kkt"][k] == f["kkt"][k] for k in KKT))
    case = os.path.relpath(case, ROOT) if case.startswith(ROOT) else case
    rows.append({"case": case, "outer": [b["outer_iterations"], f["outer_iterations"]],
                 "matvecs": [b["matvecs"], f["matvecs"]], "energy_rel_diff": diff,
                 "identical": same})
    print(f"| {case} | {b['outer_iterations']}/{f['outer_iterations']} | "
          f"{b['matvecs']}/{f['matvecs']} | {diff:.1e} | {'yes' if same else 'NO'} |", flush=True)
print(save(a.out, {"command": "bench/compare_reports.py --before BEFORE", "rows": rows,
                   "identical": sum(r["identical"] for r in rows), "cases": len(rows)}))
