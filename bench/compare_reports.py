#!/usr/bin/env python3
"""Reports of the built-in problems from two htfeti builds, side by side: iteration counts and
the relative energy difference (one rank, one thread). BEFORE is built from an older commit, as
in bench/compare_builds.py.

Usage: bench/compare_reports.py --before /tmp/htfeti-before/b/htfeti [--after build/htfeti]
Writes bench/results/compare_reports.json."""
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
]

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--before", required=True)
p.add_argument("--after", default=os.path.join(ROOT, "build", "htfeti"))
a = p.parse_args()
rows = []
print("| case | outer before/after | matvecs before/after | energy rel. diff |")
print("|---|---|---|---:|")
for case in CASES:
    r = {}
    for label, binary in (("before", a.before), ("after", a.after)):
        r[label] = solve(case.split(), binary=binary)
    b, f = r["before"], r["after"]
    diff = abs(b["objective"] - f["objective"]) / abs(b["objective"])
    rows.append({"case": case, "outer": [b["outer_iterations"], f["outer_iterations"]],
                 "matvecs": [b["matvecs"], f["matvecs"]], "energy_rel_diff": diff})
    print(f"| {case} | {b['outer_iterations']}/{f['outer_iterations']} | "
          f"{b['matvecs']}/{f['matvecs']} | {diff:.1e} |", flush=True)
print(save("compare_reports.json", {"command": "bench/compare_reports.py --before BEFORE",
                                     "rows": rows}))
