#!/usr/bin/env python3
"""H-TFETI-DP's setup against TFETI's on the same subdomains (issue 32: at most 1.5 times), with
the automatic settings (operator, preconditioner, ordering) of each.

Cases, the cube-obstacle of examples/cube-obstacle.toml (contact, SMALBE-M):
  box    40^3 hex8, 4^3 subdomains (generated box): TFETI, clusters of 2^3 and of 4^3;
  metis  the same cube split by METIS into 64 parts (bench/cases/cube40_metis64.toml): TFETI,
         and clusters of 8 formed from those parts (cluster_split = subdomains, the same
         subdomains as TFETI's) and split from the mesh (the default; other subdomains).
Setup = the report's total less solve, reconstruction, checks and output: reading, partition
and generation excluded, assembly, factorizations, the clusters' dense blocks, the coarse
problem and the preconditioner included. Medians of --repeat runs, 1 rank x --threads threads.

Usage: bench/cluster_setup.py [--repeat 3] [--threads 2] [--cases box metis]
                              [--out cluster_setup.json]
Writes bench/results/OUT and prints a markdown table."""
import argparse
import os
import statistics

from common import ROOT, save, solve

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--repeat", type=int, default=3)
p.add_argument("--threads", type=int, default=2)
p.add_argument("--cases", nargs="+", default=["box", "metis"])
p.add_argument("--out", default="cluster_setup.json")
a = p.parse_args()

BOX = ["--problem", "cube-obstacle", "--elements", "40,40,40", "--subdomains", "4,4,4"]
METIS = [os.path.join(ROOT, "bench", "cases", "cube40_metis64.toml")]
CASES = {
    "box": [("TFETI", BOX + ["-m", 1]), ("clusters of 2^3", BOX + ["-m", 2]),
            ("clusters of 4^3", BOX + ["-m", 4])],
    "metis": [("TFETI", METIS),
              ("clusters of 8, grouped parts",
               METIS + ["--cluster-size", 8, "--cluster-split", "subdomains"]),
              ("clusters of 8, split from the mesh", METIS + ["--cluster-size", 8])],
}


def setup_s(r):
    t = r["timings"]
    return t["total"] - t["solve"] - t["reconstruction"] - t["checks"] - t.get("output", 0.0)


rows = []
for case in a.cases:
    tfeti = None
    for name, args in CASES[case]:
        reps = [solve(args, threads=a.threads) for _ in range(a.repeat)]
        r = reps[0]
        t = {k: statistics.median(x["timings"].get(k, 0.0) for x in reps)
             for k in ("setup", "factorization", "coarse_problem", "cluster_setup",
                       "preconditioner_setup", "solve", "total")}
        row = {"case": case, "method": name, "runs": a.repeat,
               "setup_s": statistics.median(setup_s(x) for x in reps), "timings": t,
               "preconditioner": r["preconditioner"], "dual_operator": r["dual_operator"],
               "products": r["matvecs"], "outer_iterations": r["outer_iterations"],
               "subdomains": r["subdomains"], "clusters": r["clusters"],
               "energy": r["objective"]}
        if tfeti is None:
            tfeti = row["setup_s"]
        row["setup_to_tfeti"] = row["setup_s"] / tfeti
        rows.append(row)
        print(f"{case:6s} {name:36s} setup {row['setup_s']:6.2f} s "
              f"({row['setup_to_tfeti']:.2f} x TFETI), products {row['products']}", flush=True)

print("\n| case | method | setup s | / TFETI | factorization s | coarse s | preconditioner "
      "setup s | products | total s |")
print("|---|---|---:|---:|---:|---:|---:|---:|---:|")
for r in rows:
    t = r["timings"]
    print(f"| {r['case']} | {r['method']} | {r['setup_s']:.2f} | {r['setup_to_tfeti']:.2f} | "
          f"{t['factorization']:.2f} | {t['coarse_problem']:.2f} | "
          f"{t['preconditioner_setup']:.2f} | {r['products']} | {t['total']:.2f} |")
print("\nwritten:", save(a.out, {"command": "bench/cluster_setup.py " + " ".join(
    f"--{k.replace('_', '-')} {' '.join(map(str, v)) if isinstance(v, list) else v}"
    for k, v in vars(a).items()), "threads": a.threads, "rows": rows}))
