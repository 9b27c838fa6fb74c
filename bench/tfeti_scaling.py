#!/usr/bin/env python3
"""TFETI numerical scalability on poisson2d: PCG iterations at fixed H_s/h as the number of
subdomains grows (DESIGN.md; theory: iterations bounded in terms of H/h only).

Usage: bench/tfeti_scaling.py [--hh 16] [--ns 2 4 8 16 32] [--rtol 1e-4] [--element q1]
Writes bench/results/tfeti_scaling.json and prints a markdown table."""
import argparse

from common import save, solve

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--hh", type=int, default=16, help="H_s/h, elements per subdomain side")
p.add_argument("--ns", type=int, nargs="+", default=[2, 4, 8, 16, 32])
p.add_argument("--rtol", type=float, default=1e-4)
p.add_argument("--element", default="q1")
p.add_argument("--problem", default="poisson2d")
a = p.parse_args()

rows = []
print(f"| N_s | subdomains | n | primal | dual | coarse | PCG iterations | F applications | solve s |")
print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
for ns in a.ns:
    r = solve(["--problem", a.problem, "--element", a.element, "-n", ns * a.hh,
               "--subdomains", ns, "--rtol", a.rtol])
    rows.append(r)
    print(f"| {ns} | {r['subdomains']} | {r['elements']} | {r['primal_dimension']} | "
          f"{r['dual_dimension']} | {r['coarse_dimension']} | {r['outer_iterations']} | "
          f"{r['F_applications']} | {r['timings']['solve']:.2f} |", flush=True)
print("\n" + save(f"tfeti_scaling_{a.problem}_{a.element}_hh{a.hh}.json",
                  {"command": "bench/tfeti_scaling.py " + " ".join(
                      f"--{k} {' '.join(map(str, v)) if isinstance(v, list) else v}"
                      for k, v in vars(a).items()), "runs": rows}))
