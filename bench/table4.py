#!/usr/bin/env python3
"""The paper's Table 4 in its shape: the cube-obstacle contact problem (3D elasticity, hex8) with
clusters of 4 x 4 x 4 subdomains at H_s/h = 10, for k x k x k clusters, TFETI against H-TFETI-DP
(face averages of the six rigid body motions), SMALBE-M + MPRGP at eps = 1e-4.

k = 1, 2, 3, 4: 64, 512, 1,728, 4,096 subdomains; 0.2, 1.6, 5.3, 12.5 M unknowns. k = 4 is the
paper's row 1; its subdomains share one factor (docs/performance.md, "Equal subdomains of a
box"), and its peak is the assembled matrices: run it alone on a 24 GB machine.

Usage: bench/table4.py [--ks 1 2] [--threads 2] [--ranks 1] [--hh 10]
                       [--methods TFETI H-TFETI-DP] [--merge] [--out table4.json]
Writes bench/results/<out> (default table4.json) and prints the table next to the paper's
numbers. --merge keeps the other rows of that file."""
import argparse

from common import save, solve

# Paper, Table 4 row 1 (64 clusters of 4 x 4 x 4): H-TFETI-DP 169 iterations / 23.9 s, TFETI
# 117 / 24.9 s (the paper prints H-TFETI-DP first).
PAPER = {"htfeti_iterations": 169, "htfeti_seconds": 23.9, "tfeti_iterations": 117,
         "tfeti_seconds": 24.9, "subdomains": 4096, "clusters": 64}

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--ks", type=int, nargs="+", default=[1, 2])
p.add_argument("--hh", type=int, default=10, help="H_s/h")
p.add_argument("--m", type=int, default=4, help="subdomains per cluster side")
p.add_argument("--preconditioner", default="none",
               help="none (the paper's setting, the default here) | lumped | dirichlet | auto")
p.add_argument("--ranks", type=int, default=1)
p.add_argument("--threads", type=int, default=2)
p.add_argument("--extra", default="", help="further htfeti solve arguments, quoted")
p.add_argument("--methods", nargs="+", default=["TFETI", "H-TFETI-DP"],
               choices=["TFETI", "H-TFETI-DP"])
p.add_argument("--merge", action="store_true",
               help="keep the other rows of bench/results/<out> (replace equal k and method)")
p.add_argument("--out", default="table4.json", help="file name under bench/results")
a = p.parse_args()


def slim(r):
    """The report's per-node contact arrays (millions of numbers at k = 4) become counts."""
    c = r.get("contact")
    if isinstance(c, dict) and "x" in c:
        r["contact"] = {"nodes": len(c["x"]), "positive_multipliers": sum(m > 0 for m in c["multiplier"])}


runs = []
if a.merge:
    import json, os
    old = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results", a.out)
    if os.path.exists(old):
        runs = [r for r in json.load(open(old))["runs"]
                if not (r["k"] in a.ks and r["method"] in a.methods)]
    for r in runs:
        slim(r)
print(f"cube-obstacle, clusters of {a.m}^3 subdomains, H_s/h = {a.hh}, {a.ranks} ranks x "
      f"{a.threads} threads")
print("| clusters | subdomains | unknowns | method | coarse | outer | matvecs | F applications | "
      "setup s | factorization s | solve s | total s | peak RSS GB | max |u| |")
print("|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
for k in a.ks:
    s = k * a.m
    n = s * a.hh
    for method, m in (("TFETI", 1), ("H-TFETI-DP", a.m)):
        if method not in a.methods:
            continue
        r = solve(["--problem", "cube-obstacle", "--elements", n, "--subdomains", s,
                   "--cluster-size", m, "--preconditioner", a.preconditioner, *a.extra.split()], ranks=a.ranks, threads=a.threads)
        r["method"] = method
        r["k"] = k
        slim(r)
        runs.append(r)
        save(a.out, {"command": "(partial)", "paper": PAPER, "runs": runs})
        t = r["timings"]
        print(f"| {k}x{k}x{k} | {r['subdomains']} | {r['primal_dimension']} | {method} | "
              f"{r['coarse_dimension']} | {r['outer_iterations']} | {r['matvecs']} | "
              f"{r['F_applications']} | {t['setup']:.1f} | {t['factorization']:.1f} | "
              f"{t['solve']:.1f} | {t['total']:.1f} | "
              f"{r['memory']['peak_rss_mb_max_rank'] / 1024:.1f} | "
              f"{r['displacement']['max_norm']:.4f} |", flush=True)
runs.sort(key=lambda r: (r["k"], r["method"] != "TFETI"))
cmd = f"bench/table4.py --ks {' '.join(map(str, a.ks))} --hh {a.hh} --ranks {a.ranks} --threads {a.threads}"
if a.merge:
    cmd = "bench/table4.py (rows merged from separate runs, see docs/results.md)"
print("\n" + save(a.out, {"command": cmd, "paper": PAPER, "runs": runs}))
