#!/usr/bin/env python3
"""The coarse factor on every rank against a subset of ranks (--coarse-ranks K: the first rank of
each of K groups of consecutive ranks factors G~ G~^T, solves and broadcasts the solution to its
group), on TFETI with a large coarse problem: the cube-obstacle with --elements E and
--subdomains S (S^3 subdomains, 6 S^3 coarse unknowns).

For each K it reports medians over --repeat runs of the summed and the largest per-rank peak
memory, the coarse phase of the setup (assembly and factorization), the solve and the wall time,
and checks that the energy, the counts and the multiplier norm are the same bits for every K.

Usage: bench/coarse_ranks.py [--elements 64] [--subdomains 16] [--ranks 4] [--threads 1]
       [--ks 0 2 1] [--repeat 3] [--out coarse_ranks.json]"""
import argparse
import statistics

from common import save, solve

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--elements", type=int, default=64)
p.add_argument("--subdomains", type=int, default=16)
p.add_argument("--ranks", type=int, default=4)
p.add_argument("--threads", type=int, default=1)
p.add_argument("--ks", type=int, nargs="+", default=[0, 2, 1])
p.add_argument("--repeat", type=int, default=3)
p.add_argument("--out", default="coarse_ranks.json")
a = p.parse_args()

args = ["--problem", "cube-obstacle", "--elements", a.elements, "--subdomains", a.subdomains]
runs, rows = [], []
by = {k: [] for k in a.ks}
for _ in range(a.repeat):
    for k in a.ks:  # the settings take turns, so a slow minute of the machine hits all of them
        r = solve(args + ["--coarse-ranks", k], ranks=a.ranks, threads=a.threads)
        r.pop("contact", None)
        r["coarse_ranks_asked"] = k
        runs.append(r)
        by[k].append(r)
        save(a.out, {"command": "(partial)", "runs": runs})

print(f"cube-obstacle, {a.elements}^3 hex8, {a.subdomains}^3 subdomains (TFETI), {a.ranks} ranks x "
      f"{a.threads} threads, medians of {a.repeat}")
print("| --coarse-ranks | ranks holding the factor | coarse factor MB (one copy) | peak MB, all "
      "ranks | peak MB, fullest rank | coarse setup s | solve s | wall s | products | energy |")
print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|")
ref = by[a.ks[0]][0]
same = True
for k in a.ks:
    rs = by[k]
    med = lambda f: statistics.median(f(r) for r in rs)  # noqa: E731
    m = rs[0]["memory"]
    for r in rs:
        same = same and all(r[f] == ref[f] for f in ("objective", "matvecs", "outer_iterations"))
        same = same and r["solver"]["multiplier_norm"] == ref["solver"]["multiplier_norm"]
    row = {"coarse_ranks": k, "factor_ranks": m["coarse_factor_ranks"],
           "coarse_dimension": rs[0]["coarse_dimension"],
           "coarse_factor_mb": 8 * m["coarse_factor_nonzeros"] / 2**20,
           "peak_total_mb": med(lambda r: r["memory"]["peak_rss_mb_total"]),
           "peak_max_rank_mb": med(lambda r: r["memory"]["peak_rss_mb_max_rank"]),
           "coarse_s": med(lambda r: r["timings"]["coarse_problem"]),
           "solve_s": med(lambda r: r["timings"]["solve"]),
           "wall_s": med(lambda r: r["wall_seconds"]),
           "products": rs[0]["matvecs"], "energy": rs[0]["objective"]}
    rows.append(row)
    print(f"| {k} | {row['factor_ranks']} | {row['coarse_factor_mb']:.0f} | "
          f"{row['peak_total_mb']:.0f} | {row['peak_max_rank_mb']:.0f} | {row['coarse_s']:.2f} | "
          f"{row['solve_s']:.2f} | {row['wall_s']:.1f} | {row['products']} | {row['energy']!r} |")
print("same energy, counts and multiplier norm for every K:", same)
cmd = (f"bench/coarse_ranks.py --elements {a.elements} --subdomains {a.subdomains} --ranks "
       f"{a.ranks} --threads {a.threads} --ks {' '.join(map(str, a.ks))} --repeat {a.repeat} "
       f"--out {a.out}")
print("\n" + save(a.out, {"command": cmd, "same_bits": same, "summary": rows, "runs": runs}))
if not same:
    raise SystemExit("the solution differs between the settings")
