#!/usr/bin/env python3
"""The automatic dual operator's rule for speed, measured: each case solved with the explicit
and with the implicit operator (`--dual-operator`), the rest as the defaults give it. 3D: the
cube-obstacle of Table 4 (rows 1x1x1 and 2x2x2, TFETI and H-TFETI-DP, no preconditioner as in
the table) and the 40^3 cube split by METIS into 64 parts (bench/cases/cube40_metis64.toml,
issue 32); 2D: Table 3 reduced (m = 1 and 4). Per case and operator: Hessian products,
the factorization phase (for the explicit operator it includes forming the F_i), the time in F,
the whole run (`timings.total`), peak RSS and the energy; medians of --repeat runs for the cases
under a minute, one run above.

Usage: bench/operator_choice.py [--repeat 3] [--threads 2] [--out operator_choice.json]
Writes bench/results/OUT and prints the table with the ratio explicit / implicit of the totals."""
import argparse
import os
import statistics

from common import ROOT, machine, save, solve

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--repeat", type=int, default=3)
p.add_argument("--threads", type=int, default=2)
p.add_argument("--out", default="operator_choice.json")
a = p.parse_args()

CUBE = ["--problem", "cube-obstacle", "--preconditioner", "none"]
CASES = [
    ("3D Table 4 1x1x1 TFETI", CUBE + ["--elements", 40, "--subdomains", 4, "--cluster-size", 1]),
    ("3D Table 4 1x1x1 H-TFETI-DP", CUBE + ["--elements", 40, "--subdomains", 4,
                                            "--cluster-size", 4]),
    ("3D cube 40^3 split by METIS, 64 parts",
     [os.path.join(ROOT, "bench", "cases", "cube40_metis64.toml")]),
    ("3D Table 4 2x2x2 TFETI", CUBE + ["--elements", 80, "--subdomains", 8, "--cluster-size", 1]),
    ("3D Table 4 2x2x2 H-TFETI-DP", CUBE + ["--elements", 80, "--subdomains", 8,
                                            "--cluster-size", 4]),
    ("2D Table 3 reduced m = 1", ["--problem", "membranes", "-n", 512, "--subdomains", 32, "-m", 1]),
    ("2D Table 3 reduced m = 4", ["--problem", "membranes", "-n", 512, "--subdomains", 32, "-m", 4]),
]

rows = []
print("| case | operator | products | factorization s | F s | total s | peak RSS GB | energy |")
print("|---|---|---:|---:|---:|---:|---:|---:|")
for name, args in CASES:
    totals = {}
    for op in ("explicit", "implicit"):
        runs = []
        for _ in range(a.repeat):
            runs.append(solve([*args, "--dual-operator", op], threads=a.threads))
            if runs[-1]["timings"]["total"] > 60:
                break
        med = lambda key: statistics.median(r["timings"][key] for r in runs)  # noqa: E731
        r = runs[0]
        row = {"case": name, "operator": op, "runs": len(runs), "products": r["matvecs"],
               "outer_iterations": r["outer_iterations"], "factorization_s": med("factorization"),
               "F_s": med("F"), "total_s": med("total"),
               "peak_rss_gb": max(x["memory"]["peak_rss_mb_max_rank"] for x in runs) / 1024,
               "energy": r["objective"]}
        rows.append(row)
        totals[op] = row["total_s"]
        print(f"| {name} | {op} | {row['products']} | {row['factorization_s']:.2f} | "
              f"{row['F_s']:.2f} | {row['total_s']:.2f} | {row['peak_rss_gb']:.2f} | "
              f"{row['energy']:.10e} |", flush=True)
    print(f"| {name} | explicit / implicit | | | | {totals['explicit'] / totals['implicit']:.2f} "
          f"| | |", flush=True)
cmd = f"bench/operator_choice.py --repeat {a.repeat} --threads {a.threads}"
print("\n" + save(a.out, {"command": cmd, "machine": machine(), "rows": rows}))
