#!/usr/bin/env python3
"""The paper's Table 2 in its shape: poisson2d (Q1), clusters of m x m subdomains joined by edge
averages against TFETI, unpreconditioned projected CG at eps = 1e-4: iterations and seconds.
The paper: H_s/h = 100, m = 15, 6 x 6 clusters (8,100 subdomains, 81,018,001 unknowns) and up;
here the same m and cluster layout at sizes that fit this machine.

Usage: bench/table2.py [--hh 20] [--m 15] [--nc 1 2 3] [--ranks 1] [--threads 2]
Writes bench/results/table2_hh<H>_m<m>.json and prints a markdown table."""
import argparse

from common import save, solve

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--hh", type=int, default=20, help="H_s/h")
p.add_argument("--m", type=int, default=15, help="cluster size m (m x m subdomains)")
p.add_argument("--nc", type=int, nargs="+", default=[1, 2, 3], help="clusters per side")
p.add_argument("--ranks", type=int, default=1)
p.add_argument("--threads", type=int, default=2)
a = p.parse_args()

runs = []
print(f"poisson2d, H_s/h = {a.hh}, clusters of {a.m} x {a.m}, {a.ranks} ranks x {a.threads} threads")
print("| clusters | subdomains | unknowns | H-TFETI-DP iter / solve s / total s | "
      "TFETI iter / solve s / total s | coarse dim H / T |")
print("|---:|---:|---:|---|---|---|")
for nc in a.nc:
    ns = nc * a.m
    n = ns * a.hh
    common = ["--problem", "poisson2d", "-n", n, "--subdomains", ns]
    h = solve(common + ["-m", a.m], ranks=a.ranks, threads=a.threads)
    t = solve(common + ["-m", 1], ranks=a.ranks, threads=a.threads)
    runs.append({"hybrid": h, "tfeti": t})
    unknowns = (n + 1) ** 2
    print(f"| {nc * nc} | {ns * ns} | {unknowns:,} | {h['outer_iterations']} / "
          f"{h['timings']['solve']:.2f} / {h['timings']['total']:.2f} | {t['outer_iterations']} / "
          f"{t['timings']['solve']:.2f} / {t['timings']['total']:.2f} | "
          f"{h['coarse_dimension']} / {t['coarse_dimension']} |", flush=True)
cmd = f"bench/table2.py --hh {a.hh} --m {a.m} --nc {' '.join(map(str, a.nc))} " \
      f"--ranks {a.ranks} --threads {a.threads}"
print("\n" + save(f"table2_hh{a.hh}_m{a.m}.json", {"command": cmd, "runs": runs}))
