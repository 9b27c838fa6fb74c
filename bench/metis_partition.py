#!/usr/bin/env python3
"""METIS's objective for users' meshes, measured: each case split with
`--partition-objective volume` (the default: METIS_OBJTYPE_VOL, the communication volume) and
`cut` (METIS_OBJTYPE_CUT, the cut facets), the rest as the defaults give it. Cases: the
cube-obstacle split by METIS at 40^3 (64 parts) without and with the obstacle and at 80^3 (512
parts, issue 32), and the examples split by METIS (bracket, plate-with-hole, the three contact
pairs). Per case and objective: Hessian products (F for the linear cases), outer iterations,
the norm estimate's products, the equalities (interface rows), the coarse dimension, setup /
factorization / solve / total seconds, peak RSS and the energy; medians of --repeat runs for
the runs under a minute, one run above.

Usage: bench/metis_partition.py [--repeat 3] [--threads 2] [--quick] [--out metis_partition.json]
--quick leaves out the 80^3 case. Writes bench/results/OUT and prints the table."""
import argparse
import os
import statistics

from common import ROOT, machine, save, solve

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--repeat", type=int, default=3)
p.add_argument("--threads", type=int, default=2)
p.add_argument("--quick", action="store_true")
p.add_argument("--out", default="metis_partition.json")
a = p.parse_args()

CASES = os.path.join(ROOT, "bench", "cases")
EX = os.path.join(ROOT, "examples")
cases = [
    ("cube 40^3, 64 parts, no obstacle", os.path.join(CASES, "cube40_metis64_linear.toml")),
    ("cube-obstacle 40^3, 64 parts", os.path.join(CASES, "cube40_metis64.toml")),
    ("cube-obstacle 80^3, 512 parts", os.path.join(CASES, "cube80_metis512.toml")),
    ("bracket (tet4, 12 parts)", os.path.join(EX, "bracket.toml")),
    ("plate-with-hole (tri3, 16 parts)", os.path.join(EX, "plate-with-hole.toml")),
    ("cylinder-on-block (2D pair)", os.path.join(EX, "cylinder-on-block.toml")),
    ("sphere-on-block (3D pair, tet4)", os.path.join(EX, "sphere-on-block.toml")),
    ("punch-on-block (3D pair, hex8)", os.path.join(EX, "punch-on-block.toml")),
]
if a.quick:
    cases = [c for c in cases if "80^3" not in c[0]]

rows = []
print("| case | objective | products | outer | norm est. | equalities | coarse | setup s | "
      "factorization s | solve s | total s | peak RSS GB | energy |")
print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
for name, path in cases:
    for objective in ("volume", "cut"):
        runs = []
        for _ in range(a.repeat):
            runs.append(solve([path, "--partition-objective", objective], threads=a.threads))
            if runs[-1]["timings"]["total"] > 60:
                break
        med = lambda key: statistics.median(r["timings"][key] for r in runs)  # noqa: E731
        r = runs[0]
        row = {"case": name, "objective": objective, "runs": len(runs),
               "products": r["matvecs"], "outer_iterations": r["outer_iterations"],
               "norm_estimate_products": r["solver"].get("norm_estimate_matvecs", 0),
               "equalities": r["equalities"], "coarse_dimension": r["coarse_dimension"],
               "setup_s": med("setup"), "factorization_s": med("factorization"),
               "solve_s": med("solve"), "total_s": med("total"),
               "wall_s": statistics.median(x["wall_seconds"] for x in runs),
               "peak_rss_gb": max(x["memory"]["peak_rss_mb_max_rank"] for x in runs) / 1024,
               "energy": r["objective"]}
        rows.append(row)
        print(f"| {name} | {objective} | {row['products']} | {row['outer_iterations']} | "
              f"{row['norm_estimate_products']} | {row['equalities']} | "
              f"{row['coarse_dimension']} | {row['setup_s']:.2f} | {row['factorization_s']:.2f} | "
              f"{row['solve_s']:.2f} | {row['total_s']:.2f} | {row['peak_rss_gb']:.2f} | "
              f"{row['energy']:.12e} |", flush=True)
save(a.out, {"machine": machine(), "threads": a.threads, "repeat": a.repeat, "rows": rows})
