#!/usr/bin/env python3
"""Setup cost per subdomain: htfeti's explicit-operator setup against CHOLMOD's plain
factorization of the same matrix, in 2D and 3D, for one or two builds (before / after a change).

Cases (one thread, so that milliseconds per subdomain are core-milliseconds):
  2d  membranes, n = 792, N_s = 8: 128 subdomains of 100 x 100 nodes (the Table 3 subdomain);
  3d  cube-obstacle, 40^3 hex8, 4^3 subdomains: 64 subdomains of 11^3 nodes (Table 4's).
The symbolic analysis is shared between subdomains of one pattern (the JSON records the analyses
and reuses), so its cost per subdomain falls with the number of subdomains.
Per build and case, medians of --repeat runs, from the reports:
  - "factorization" phase per subdomain with the explicit operator (interface-last factor,
    the dense F_i, d, the kernel blocks);
  - the reference "CHOLMOD plain": the implicit operator with AMD (2D) / METIS (3D) and no
    shared analyses, whose per-subdomain work is forming K_rr plus cholmod_analyze and
    cholmod_factorize (the report's factorization.symbolic_core_s + numeric_core_s; builds
    without that report key give only the phase time);
  - the reconstruction per subdomain (here the factors are kept: one solve per subdomain).

Usage: bench/setup_cost.py [--before OLD/htfeti] [--after build/htfeti] [--repeat 3]
                           [--cases 2d 3d] [--after-args "--numeric-cache 0"]
--after-args: further arguments for the after build's explicit runs (the committed rows were
measured before the numeric cache existed: pass "--numeric-cache 0" to compare like with like).
The builds take turns run by run (one run of each per repetition), so that the drift of a shared
machine's speed falls on all of them alike.
Writes bench/results/setup_cost.json and prints a markdown table."""
import argparse
import os
import statistics

import json

from common import RESULTS, ROOT, save, solve

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--before", default=None, help="an older htfeti binary")
p.add_argument("--after", default=os.path.join(ROOT, "build", "htfeti"))
p.add_argument("--repeat", type=int, default=3)
p.add_argument("--cases", nargs="+", default=["2d", "3d"], help="2d and/or 3d")
p.add_argument("--after-args", default="", help="further arguments for the after build")
a = p.parse_args()

CASES = {
    "2d": ["--problem", "membranes", "-n", 792, "--subdomains", 8],
    "3d": ["--problem", "cube-obstacle", "--elements", "40,40,40", "--subdomains", "4,4,4",
           "--preconditioner", "none"],
}


def summarize(runs):
    n = runs[0]["subdomains"]
    med = lambda f: statistics.median(f(r) for r in runs) / n * 1e3  # noqa: E731
    out = {"factorization_ms": med(lambda r: r["timings"]["factorization"]),
           "reconstruction_ms": med(lambda r: r["timings"]["reconstruction"]),
           "matvecs": runs[0]["matvecs"], "objective": runs[0]["objective"],
           "dual_operator": runs[0]["dual_operator"], "subdomains": n}
    f = runs[0].get("factorization")
    if f:
        out["symbolic_ms"] = med(lambda r: r["factorization"]["symbolic_core_s"])
        out["numeric_ms"] = med(lambda r: r["factorization"]["numeric_core_s"])
        out["symbolic_analyses"] = f["symbolic_analyses"]
        out["symbolic_reuses"] = f["symbolic_reuses"]
    return out


builds = [("after", a.after)] + ([("before", a.before)] if a.before else [])
result = {"command": "bench/setup_cost.py" + (" --before BEFORE" if a.before else "") +
          f" --repeat {a.repeat}" + (f' --after-args "{a.after_args}"' if a.after_args else ""),
          "cases": {}}
path = os.path.join(RESULTS, "setup_cost.json")
if os.path.exists(path):  # cases not rerun are kept
    with open(path) as f:
        result["cases"] = json.load(f).get("cases", {})
for case in a.cases:
    args = CASES[case]
    # The builds and the plain reference take turns, one run each per repetition: this VM's
    # speed drifts over minutes, and interleaving spreads the drift over all of them alike.
    variants = [(label, binary, args + ["--dual-operator", "explicit"] +
                 (a.after_args.split() if label == "after" else []))
                for label, binary in builds]
    variants.append(("plain", a.after,
                     args + ["--dual-operator", "implicit", "--symbolic-cache", 0]))
    runs = {label: [] for label, _, _ in variants}
    for _ in range(a.repeat):
        for label, binary, v in variants:
            runs[label].append(solve(v, threads=1, binary=binary))
    row = {label: summarize(runs[label]) for label, _ in builds}
    plain = summarize(runs["plain"])
    row["cholmod_plain_ms"] = plain.get("symbolic_ms", 0) + plain.get("numeric_ms", 0)
    row["cholmod_plain"] = plain
    row["interleaved"] = True
    result["cases"][case] = row
    save("setup_cost.json", result)

print("| case | build | explicit setup ms / subdomain | of which symbolic / numeric ms | "
      "reconstruction ms / subdomain | CHOLMOD plain ms (analyze + factorize) | matvecs |")
print("|---|---|---:|---|---:|---:|---:|")
for case, row in result["cases"].items():
    for label, _ in builds:
        if label not in row:
            continue
        r = row[label]
        split = (f"{r['symbolic_ms']:.1f} / {r['numeric_ms']:.1f}" if "symbolic_ms" in r else "-")
        print(f"| {case} | {label} | {r['factorization_ms']:.1f} | {split} | "
              f"{r['reconstruction_ms']:.1f} | {row['cholmod_plain_ms']:.1f} | {r['matvecs']} |")
print("\nwritten:", save("setup_cost.json", result))
