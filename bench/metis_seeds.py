#!/usr/bin/env python3
"""METIS's seed and the solver's iterations (issue 32): the cube-obstacle split by METIS with
seeds 1..S (`--partition-seed`), beside the same cube split into equal boxes. METIS's splits
from different seeds are equally good by METIS's measure, but the FETI operator's largest
eigenvalue (the report's norm estimate) follows the worst-shaped part and the products follow
it, so one METIS split is one draw. This script gives the spread and the median over seeds,
the number to hold against the box split.

Per run: Hessian products (without the norm estimate's, which are listed apart), outer
iterations, the norm estimate ||PFP||, the dual dimension, the solve's seconds and the
energy; per case the median, smallest and largest products over the seeds and the median's
ratio to the box split's products. Counts only need one run each (they do not depend on the
machine's speed); times are single runs, for orientation.

Usage: bench/metis_seeds.py [--n 40] [--amplitudes 1 20] [--seeds 8] [--threads 2]
                            [--out metis_seeds.json]
The cube is n^3 hex8 cells in (n/10)^3 parts (64 at n = 40, 512 at n = 80), the problem of
bench/cases/cube40_metis64*.toml and bench/cube_obstacle_peer.py. Writes bench/results/OUT."""
import argparse
import statistics
import tempfile

from common import cube_obstacle_file, machine, save, solve

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--n", type=int, default=40)
p.add_argument("--amplitudes", type=float, nargs="+", default=[1.0, 20.0])
p.add_argument("--seeds", type=int, default=8)
p.add_argument("--threads", type=int, default=2)
p.add_argument("--out", default="metis_seeds.json")
a = p.parse_args()
if a.n % 10:
    p.error("--n must be a multiple of 10 (parts of 10^3 cells)")

ns = a.n // 10


def case_file(d, amplitude, subdomains):
    return cube_obstacle_file(d, a.n, amplitude, subdomains)


def row_of(r, split, seed):
    s = r["solver"]
    return {"split": split, "seed": seed, "products": r["matvecs"],
            "norm_estimate_products": s.get("norm_estimate_matvecs", 0),
            "outer_iterations": r["outer_iterations"], "norm_estimate": s["norm_estimate"],
            "expansion_steps": s.get("expansion_steps"), "dual_dimension": r["dual_dimension"],
            "partition_repaired_cells": r.get("partition_repaired_cells"),
            "partition_contiguous_splits": r.get("partition_contiguous_splits"),
            "solve_s": r["timings"]["solve"], "wall_s": r["wall_seconds"],
            "energy": r["objective"]}


cases = []
with tempfile.TemporaryDirectory() as d:
    for amplitude in a.amplitudes:
        box = row_of(solve([case_file(d, amplitude, f"[{ns}, {ns}, {ns}]")], threads=a.threads),
                     "box", None)
        print(f"A = {amplitude:g}, box: {box['products']} products, ||PFP|| "
              f"{box['norm_estimate']:.3g}", flush=True)
        metis_file = case_file(d, amplitude, str(ns ** 3))
        runs = []
        for seed in range(1, a.seeds + 1):
            r = row_of(solve([metis_file, "--partition-seed", seed], threads=a.threads),
                       "metis", seed)
            runs.append(r)
            print(f"A = {amplitude:g}, METIS seed {seed}: {r['products']} products, ||PFP|| "
                  f"{r['norm_estimate']:.3g}, {r['outer_iterations']} outer", flush=True)
        products = [r["products"] for r in runs]
        med = statistics.median(products)
        cases.append({"n": a.n, "parts": ns ** 3, "amplitude": amplitude, "box": box,
                      "metis": runs, "metis_products_median": med,
                      "metis_products_min": min(products), "metis_products_max": max(products),
                      "median_to_box": med / box["products"],
                      "norm_median_to_box": statistics.median(r["norm_estimate"] for r in runs)
                      / box["norm_estimate"]})

print()
print("| n | A | box products | METIS products: median (min-max) over seeds | median / box | "
      "||PFP|| median / box |")
print("|---:|---:|---:|---|---:|---:|")
for c in cases:
    print(f"| {c['n']} | {c['amplitude']:g} | {c['box']['products']} | "
          f"{c['metis_products_median']:g} ({c['metis_products_min']}-{c['metis_products_max']}) | "
          f"{c['median_to_box']:.2f} | {c['norm_median_to_box']:.2f} |")
save(a.out, {"machine": machine(), "threads": a.threads, "seeds": a.seeds, "cases": cases})
