#!/usr/bin/env python3
"""The layered Dirichlet preconditioner on METIS parts (issue 32): the cube-obstacle split by
METIS with seeds 1..S, solved with the lumped preconditioner, the Dirichlet one on k layers of
interior dofs next to the interface (`--dirichlet-layers k`, the rest of each part clamped) and
the Dirichlet one on the whole interior, all with the implicit storage; beside the same cube
split into equal boxes with the automatic settings (lumped), the products to hold them against.

Per run: Hessian products (the norm estimate's included, as everywhere), MPRGP's expansion
steps, the preconditioner's setup (thread-seconds, part of the factorization phase) and
application (seconds), the factorization phase, the solve phase, the report's total and the
process's wall time, and the energy. Per variant and amplitude the median, smallest and largest
products over the seeds, the median's ratio to the box's products, and the median times.
Counts need one run each (any machine gives them); times are single runs, for orientation.

Usage: bench/dirichlet_layers.py [--n 40] [--parts P] [--amplitudes 1 20] [--seeds 8]
                                 [--variants lumped layers1 layers2 dirichlet] [--threads 2]
                                 [--out dirichlet_layers.json]
The cube is n^3 hex8 cells (the problem of bench/cases/cube40_metis64*.toml), by default in
(n/10)^3 parts (64 at n = 40, 512 at n = 80); --parts sets another count for the METIS split
(the box split then needs a cube number of parts). Writes bench/results/OUT."""
import argparse
import statistics
import tempfile

from common import cube_obstacle_file, save, solve

VARIANTS = {
    "lumped": ["--preconditioner", "lumped"],
    "dirichlet": ["--preconditioner", "dirichlet", "--dirichlet-storage", "implicit"],
}
for k in range(1, 10):
    VARIANTS[f"layers{k}"] = ["--preconditioner", "dirichlet", "--dirichlet-storage", "implicit",
                              "--dirichlet-layers", str(k)]

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--n", type=int, default=40)
p.add_argument("--parts", type=int, default=None)
p.add_argument("--amplitudes", type=float, nargs="+", default=[1.0, 20.0])
p.add_argument("--seeds", type=int, default=8)
p.add_argument("--variants", nargs="+", default=["lumped", "layers1", "layers2", "dirichlet"],
               choices=sorted(VARIANTS))
p.add_argument("--threads", type=int, default=2)
p.add_argument("--out", default="dirichlet_layers.json")
a = p.parse_args()
parts = a.parts if a.parts else (a.n // 10) ** 3
side = round(parts ** (1 / 3))
if side ** 3 != parts:
    p.error("--parts must be a cube number (the box split beside it)")
if a.n % side:
    p.error("--n must be a multiple of the parts per side")


def case_file(d, amplitude, subdomains):
    return cube_obstacle_file(d, a.n, amplitude, subdomains)


def row_of(r, variant, seed):
    t = r["timings"]
    return {"variant": variant, "seed": seed, "products": r["matvecs"],
            "expansion_steps": r["solver"].get("expansion_steps"),
            "preconditioner": r.get("preconditioner"),
            "preconditioner_layers": r.get("preconditioner_layers"),
            "preconditioner_setup_thread_s": t.get("preconditioner_setup", 0.0),
            "preconditioner_s": t.get("preconditioner", 0.0),
            "preconditioner_mb": r["memory"].get("preconditioner_mb"),
            "factorization_s": t["factorization"], "solve_s": t["solve"], "F_s": t["F"],
            "total_s": t["total"], "wall_s": r["wall_seconds"], "energy": r["objective"]}


def median(runs, key):
    return statistics.median(r[key] for r in runs)


cases = []
with tempfile.TemporaryDirectory() as d:
    for amplitude in a.amplitudes:
        box = row_of(solve([case_file(d, amplitude, f"[{side}, {side}, {side}]")],
                           threads=a.threads), "box (automatic: lumped)", None)
        print(f"A = {amplitude:g}, box: {box['products']} products", flush=True)
        metis_file = case_file(d, amplitude, str(parts))
        for variant in a.variants:
            runs = []
            for seed in range(1, a.seeds + 1):
                r = row_of(solve([metis_file, "--partition-seed", seed, *VARIANTS[variant]],
                                 threads=a.threads), variant, seed)
                runs.append(r)
                print(f"A = {amplitude:g}, {variant}, seed {seed}: {r['products']} products, "
                      f"setup {r['preconditioner_setup_thread_s']:.2f} thread-s, total "
                      f"{r['total_s']:.2f} s", flush=True)
            products = [r["products"] for r in runs]
            cases.append({"n": a.n, "parts": parts, "amplitude": amplitude, "variant": variant,
                          "box": box, "runs": runs,
                          "products_median": statistics.median(products),
                          "products_min": min(products), "products_max": max(products),
                          "median_to_box": statistics.median(products) / box["products"],
                          "total_s_median": median(runs, "total_s"),
                          "wall_s_median": median(runs, "wall_s"),
                          "setup_thread_s_median": median(runs, "preconditioner_setup_thread_s"),
                          "preconditioner_s_median": median(runs, "preconditioner_s")})

print()
print("| n | parts | A | variant | products: median (min-max) over seeds | median / box | "
      "preconditioner setup thread-s | preconditioner s | total s | wall s |")
print("|---:|---:|---:|---|---|---:|---:|---:|---:|---:|")
for c in cases:
    print(f"| {c['n']} | {c['parts']} | {c['amplitude']:g} | {c['variant']} | "
          f"{c['products_median']:g} ({c['products_min']}-{c['products_max']}) | "
          f"{c['median_to_box']:.2f} (box {c['box']['products']}) | "
          f"{c['setup_thread_s_median']:.2f} | {c['preconditioner_s_median']:.2f} | "
          f"{c['total_s_median']:.2f} | {c['wall_s_median']:.2f} |")
save(a.out, {"threads": a.threads, "seeds": a.seeds, "cases": cases})
