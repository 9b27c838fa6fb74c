#!/usr/bin/env python3
"""Compact parts against METIS's own (`--partition-shape compact|metis`, partition.hpp): the same
problem split by METIS, its parts kept as METIS made them and moved toward compact parts
(kept where they cut fewer facets), beside the box split where the mesh is a box. Automatic
settings otherwise (TFETI, 1 rank x --threads).

Cases:
  cube40_a1, cube40_a20   the cube-obstacle of issue 32 (bench/cases/cube40_metis64*.toml: 40^3
                          hex8, 64 parts, rtol 1e-4) at A = 1 and A = 20, METIS seeds --seeds,
                          and the 4 x 4 x 4 box split;
  cube80_a1, cube80_a20   the same at 80^3 in 512 parts (8 x 8 x 8 boxes), seed 1 (with
                          --large only: about a minute and 5 GB per run);
  hertz_strong, hertz_mild, hertz_uniform, hertz_tet
                          the Hertz blocks of bench/hertz_cases.py (16 METIS parts; hex8 graded
                          strongly, mildly, uniform; tet4 with a size field), meshed by gmsh;
  bracket                 examples/bracket.toml (tet4, 12 parts in 3 clusters, PCG).
Per run: products (Hessian products or PCG's products with F), outer iterations, the norm
estimate of PFP, the dual dimension, the splits made compact and declined, the energy, the
split's seconds (timings.partition) and the report's total seconds (median of --repeat runs).

Usage: bench/compact_parts.py [--cases ...] [--large] [--seeds 1 2 3 4] [--repeat 1]
                              [--threads 2] [--out compact_parts.json]"""
import argparse
import os
import statistics
import tempfile

from common import ROOT, save, solve

CASES_DIR = os.path.join(ROOT, "bench", "cases")
SMALL = ["cube40_a1", "cube40_a20", "hertz_strong", "hertz_mild", "hertz_uniform", "hertz_tet",
         "bracket"]
LARGE = ["cube80_a1", "cube80_a20"]

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--cases", nargs="+", choices=SMALL + LARGE)
p.add_argument("--large", action="store_true", help="add the 80^3 cubes")
p.add_argument("--seeds", nargs="+", type=int, default=[1])
p.add_argument("--repeat", type=int, default=1)
p.add_argument("--threads", type=int, default=2)
p.add_argument("--out", default="compact_parts.json")
a = p.parse_args()
names = a.cases or SMALL + (LARGE if a.large else [])


def row_of(runs):
    r = runs[0]
    return {"stop_reason": r["stop_reason"], "products": r["matvecs"],
            "outer": r.get("outer_iterations"), "norm_estimate": r["solver"].get("norm_estimate"),
            "dual_dimension": r["dual_dimension"],
            "compact_splits": r.get("partition_compact_splits"),
            "compact_declined": r.get("partition_compact_declined"), "energy": r["objective"],
            "partition_s": statistics.median(x["timings"].get("partition", 0) for x in runs),
            "total_s": statistics.median(x["timings"]["total"] for x in runs)}


def runs(args):
    return row_of([solve(args, threads=a.threads) for _ in range(a.repeat)])


rows = []
with tempfile.TemporaryDirectory() as d:
    hertz = {}
    if any(n.startswith("hertz") for n in names):
        import hertz_cases
        files = [f for _, f in hertz_cases.contact_problems(d)]
        hertz = dict(zip(["hertz_strong", "hertz_mild", "hertz_uniform", "hertz_tet"], files))
    for name in names:
        if name.startswith("cube"):
            n, amp = name[4:6], name.split("_a")[1]
            parts = "64" if n == "40" else "512"
            f = os.path.join(CASES_DIR, f"cube{n}_metis{parts}" + ("_a20" if amp == "20" else "")
                             + ".toml")
            boxes = "4,4,4" if n == "40" else "8,8,8"
            seeds = a.seeds if n == "40" else [1]
        else:
            f = hertz.get(name) or os.path.join(ROOT, "examples", "bracket.toml")
            boxes, seeds = None, a.seeds[:1]
        for seed in seeds:
            row = {"case": name, "seed": seed}
            for shape in ("metis", "compact"):
                row[shape] = runs([f, "--partition-shape", shape, "--partition-seed", seed])
            m, c = row["metis"], row["compact"]
            print(f"{name} seed {seed}: products {m['products']} -> {c['products']}, "
                  f"norm {m['norm_estimate'] or 0:.3g} -> {c['norm_estimate'] or 0:.3g}, dual "
                  f"{m['dual_dimension']} -> {c['dual_dimension']}, compact "
                  f"{c['compact_splits']}/{c['compact_declined']}, total {m['total_s']:.2f} -> "
                  f"{c['total_s']:.2f} s", flush=True)
            rows.append(row)
        if boxes:
            row = {"case": name, "box": runs([f, "--subdomains", boxes])}
            print(f"{name} box split: products {row['box']['products']}, total "
                  f"{row['box']['total_s']:.2f} s", flush=True)
            rows.append(row)

save(a.out, {"command": "bench/compact_parts.py", "threads": a.threads, "repeat": a.repeat,
             "rows": rows})
