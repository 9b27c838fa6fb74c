#!/usr/bin/env python3
"""The paper's Table 2 in its shape: poisson2d (Q1), clusters of m x m subdomains joined by edge
averages against TFETI, unpreconditioned projected CG at eps = 1e-4: iterations and seconds.
The paper: H_s/h = 100, m = 15, 6 x 6 clusters (8,100 subdomains, 81,018,001 unknowns) and up;
here the same m and cluster layout at sizes that fit this machine.

Usage: bench/table2.py [--hh 20] [--m 15] [--nc 1 2 3] [--ranks 1] [--threads 2]
                       [--methods hybrid tfeti] [--extra "ARGS"] [--vtu] [--out FILE]
Writes bench/results/table2_hh<H>_m<m>.json (or --out) and prints a markdown table.
The paper's row 1 on this machine (81,018,001 unknowns; the automatic operator is the explicit
one, double precision: the cost model prefers it and the memory check finds the run with it
within 3/4 of the memory):
  bench/table2.py --hh 100 --nc 6 --methods tfeti --vtu --out table2_row1_auto.json
  (--extra "--explicit-precision single": half the memory for the F_i; table2_row1.json)"""
import argparse

from common import save, solve

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--hh", type=int, default=20, help="H_s/h")
p.add_argument("--m", type=int, default=15, help="cluster size m (m x m subdomains)")
p.add_argument("--nc", type=int, nargs="+", default=[1, 2, 3], help="clusters per side")
p.add_argument("--ranks", type=int, default=1)
p.add_argument("--threads", type=int, default=2)
p.add_argument("--methods", nargs="+", choices=["hybrid", "tfeti"], default=["hybrid", "tfeti"])
p.add_argument("--extra", default="", help="further htfeti solve arguments, quoted")
p.add_argument("--vtu", action="store_true", help="write the VTU output too (timed in the report)")
p.add_argument("--out", help="the JSON file in bench/results")
a = p.parse_args()

runs = []
print(f"poisson2d, H_s/h = {a.hh}, clusters of {a.m} x {a.m}, {a.ranks} ranks x {a.threads} threads")
print("| clusters | subdomains | unknowns | H-TFETI-DP iter / solve s / total s | "
      "TFETI iter / solve s / total s | coarse dim H / T |")
print("|---:|---:|---:|---|---|---|")
for nc in a.nc:
    ns = nc * a.m
    n = ns * a.hh
    common = ["--problem", "poisson2d", "-n", n, "--subdomains", ns] + a.extra.split()
    run = {}
    for method in a.methods:
        run[method] = solve(common + ["-m", a.m if method == "hybrid" else 1], ranks=a.ranks,
                            threads=a.threads, vtu=a.vtu)
    runs.append(run)
    unknowns = (n + 1) ** 2

    def cell(r):
        if r is None:
            return "-"
        return f"{r['outer_iterations']} / {r['timings']['solve']:.2f} / {r['timings']['total']:.2f}"
    h, t = run.get("hybrid"), run.get("tfeti")
    print(f"| {nc * nc} | {ns * ns} | {unknowns:,} | {cell(h)} | {cell(t)} | "
          f"{h['coarse_dimension'] if h else '-'} / {t['coarse_dimension'] if t else '-'} |",
          flush=True)
    for method, r in run.items():
        mem = r["memory"]
        core_s = r["timings"]["total"] * a.ranks * a.threads / (unknowns / 1e6)
        line = (f"  {method}: total {r['timings']['total']:.1f} s, {core_s:.1f} core-s per M "
                f"unknowns, peak {mem['peak_rss_mb_total'] / 1024:.1f} GB, phases "
                + ", ".join(f"{k} {r['timings'][k]:.1f}" for k in
                            ("assembly", "factorization", "solve", "reconstruction")))
        if "output" in r["timings"]:
            line += f", VTU {r['output_mb']:.0f} MB in {r['timings']['output']:.1f} s"
        print(line, flush=True)
cmd = f"bench/table2.py --hh {a.hh} --m {a.m} --nc {' '.join(map(str, a.nc))} " \
      f"--ranks {a.ranks} --threads {a.threads} --methods {' '.join(a.methods)}" + \
      (f' --extra "{a.extra}"' if a.extra else "") + (" --vtu" if a.vtu else "")
print("\n" + save(a.out or f"table2_hh{a.hh}_m{a.m}.json", {"command": cmd, "runs": runs}))
