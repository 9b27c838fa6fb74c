#!/usr/bin/env python3
"""Two coarse steps per SMALBE-M Hessian product (P v, F, P: the default) against one (F v, then
[G~ v, G~ F v] in one reduction, with E = F G~^T formed in setup: --coarse-steps-per-product 1),
on the paper's Table 3 shape (membranes, 32 x 32 subdomains per membrane, clusters of m x m).

Runs the two forms in turn, --repeat times, and reports medians of:
  - the coarse work per Hessian product: two projections (2 x timings.projector /
    projector_applications) against one step (timings.merged_coarse_steps / merged_coarse_steps);
  - F per product, the solve, the setup of the coarse image (seconds, F applications, MB of E
    and C) and the peak memory;
and the counts (outer iterations, Hessian products) and energies of both forms.

Usage: bench/coarse_steps.py [--hh 16 | --full] [--ms 1 8] [--ranks 1] [--threads 2]
       [--repeat 3] [--out coarse_steps_hh16.json]"""
import argparse
import statistics

from common import save, solve

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--hh", type=int, default=16, help="H_s/h (elements per subdomain side)")
p.add_argument("--full", action="store_true", help="the paper's size, H_s/h = 99")
p.add_argument("--ms", type=int, nargs="+", default=[1, 8])
p.add_argument("--ns", type=int, default=32, help="subdomains per membrane side")
p.add_argument("--ranks", type=int, default=1)
p.add_argument("--threads", type=int, default=2)
p.add_argument("--repeat", type=int, default=3)
p.add_argument("--out", default=None)
a = p.parse_args()
hh = 99 if a.full else a.hh
n = a.ns * hh
out = a.out or f"coarse_steps_hh{hh}_r{a.ranks}t{a.threads}.json"


def per_product(r):
    t = r["timings"]
    if r["coarse_steps_per_product"] == 1:
        return t["merged_coarse_steps"] / r["merged_coarse_steps"]
    return 2 * t["projector"] / r["projector_applications"]


def products(r):
    return r["matvecs"] + r["solver"]["norm_estimate_matvecs"]


runs, rows = [], []
print(f"membranes, n = {n}, N_s = {a.ns}, H_s/h = {hh}, {a.ranks} ranks x {a.threads} threads, "
      f"medians of {a.repeat}")
print("| m | steps | outer / products | coarse work per product, ms | F per product, ms | "
      "solve s | image setup s (F applications) | E + C, MB | peak GB | energy |")
print("|---:|---:|---|---:|---:|---:|---|---:|---:|---|")
for m in a.ms:
    by = {2: [], 1: []}
    for _ in range(a.repeat):
        for steps in (2, 1):
            r = solve(["--problem", "membranes", "-n", n, "--subdomains", a.ns, "-m", m,
                       "--coarse-steps-per-product", steps], ranks=a.ranks, threads=a.threads)
            r.pop("contact", None)  # the per-node contact arrays: 0.4 MB per run, not used here
            runs.append(r)
            by[steps].append(r)
            save(out, {"command": "(partial)", "runs": runs})
    for steps in (2, 1):
        rs = by[steps]
        med = lambda f: statistics.median(f(r) for r in rs)
        img = rs[0].get("coarse_image", {})
        row = {"m": m, "steps": steps, "outer": rs[0]["outer_iterations"],
               "products": products(rs[0]),
               "coarse_ms": 1e3 * med(per_product),
               "F_ms": 1e3 * med(lambda r: r["timings"]["F"] / r["F_applications"]),
               "solve_s": med(lambda r: r["timings"]["solve"]),
               "image_s": med(lambda r: r["timings"]["coarse_image"]),
               "image_F": img.get("F_applications", 0), "image_mb": img.get("mb", 0.0),
               "peak_gb": med(lambda r: r["memory"]["peak_rss_mb_total"]) / 1024,
               "energy": rs[0]["objective"],
               "energies_equal_over_repeats": len({r["objective"] for r in rs}) == 1}
        rows.append(row)
        print(f"| {m} | {steps} | {row['outer']} / {row['products']} | {row['coarse_ms']:.3f} | "
              f"{row['F_ms']:.2f} | {row['solve_s']:.2f} | {row['image_s']:.2f} "
              f"({row['image_F']}) | {row['image_mb']:.1f} | {row['peak_gb']:.2f} | "
              f"{row['energy']:.12f} |", flush=True)
cmd = "bench/coarse_steps.py " + ("--full" if a.full else f"--hh {hh}") + \
      f" --ms {' '.join(map(str, a.ms))} --ranks {a.ranks} --threads {a.threads}" + \
      f" --repeat {a.repeat}" + (f" --out {a.out}" if a.out else "")
print("\n" + save(out, {"command": cmd, "summary": rows, "runs": runs}))
