#!/usr/bin/env python3
"""H-TFETI-DP's clusters on a METIS split: formed from the mesh (--cluster-split mesh, the
default: METIS splits the mesh into clusters, then each cluster into its subdomains) against
formed from the subdomains (--cluster-split subdomains: METIS splits the mesh into the
subdomains, then groups them by their adjacency), with TFETI on the METIS split as the yardstick.

Per case: Hessian products (PCG iterations for a linear problem; SMALBE-M's products with the
norm estimate's for contact), outer iterations, accuracy refinements (src/solve_parts.hpp), the
energy's distance from the reference (TFETI on the METIS split at rtol 1e-10: the same discrete
problem, whatever the split), and the setup, solve and wall seconds (medians of --repeat).
The problems: the cube of bench/cases (hex8, own weight, clamped at x = 0; 64 METIS parts) at
24^3 and 40^3, linear (PCG) and with the obstacle (cube-obstacle, SMALBE-M), clusters of 8 and
4; the examples split by METIS with clusters (bracket: tet4, 12 parts in clusters of 4;
plate-with-hole: 2D, 16 parts in clusters of 4); with --large also the 80^3 cube-obstacle of
512 parts in clusters of 8.

With --conditioning instead: the 24^3 cube in clusters of 8 solved to rtol 1e-10 by TFETI and
by H-TFETI-DP with both cluster splits (PCG iterations: what F's conditioning costs), written to
cluster_split_conditioning.json.

Usage: bench/cluster_split.py [--large] [--threads 2] [--repeat 3] [--out cluster_split.json]
       bench/cluster_split.py --conditioning
Writes bench/results/OUT and prints a markdown table."""
import argparse
import os
import re
import statistics
import tempfile

from common import ROOT, save, solve

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--large", action="store_true")
p.add_argument("--threads", type=int, default=2)
p.add_argument("--repeat", type=int, default=3)
p.add_argument("--out", default="cluster_split.json")
p.add_argument("--conditioning", action="store_true")
a = p.parse_args()

CASE = lambda name: os.path.join(ROOT, "bench", "cases", name)  # noqa: E731
EX = lambda name: os.path.join(ROOT, "examples", name + ".toml")  # noqa: E731
# (name, problem file, elements per side or None, cluster size)
CASES = [("cube 24^3, linear", CASE("cube40_metis64_linear.toml"), 24, 8),
         ("cube 24^3, linear", CASE("cube40_metis64_linear.toml"), 24, 4),
         ("cube 40^3, linear", CASE("cube40_metis64_linear.toml"), 40, 8),
         ("cube-obstacle 40^3", CASE("cube40_metis64.toml"), 40, 8),
         ("cube-obstacle 40^3", CASE("cube40_metis64.toml"), 40, 4),
         ("bracket (tet4, 12 parts)", EX("bracket"), None, 4),
         ("plate-with-hole (2D, 16 parts)", EX("plate-with-hole"), None, 4)]
if a.large:
    CASES.append(("cube-obstacle 80^3 (512 parts)", CASE("cube80_metis512.toml"), None, 8))


def products(r):
    return r["matvecs"] + r["solver"].get("norm_estimate_matvecs", 0)


def cube24(d):
    with open(CASE("cube40_metis64_linear.toml")) as f:
        text = re.sub(r"elements = \[\d+, \d+, \d+\]", "elements = [24, 24, 24]", f.read())
    path = os.path.join(d, "cube24.toml")
    with open(path, "w") as f:
        f.write(text)
    return path


if a.conditioning:
    rows = []
    with tempfile.TemporaryDirectory() as d:
        path = cube24(d)
        for label, extra in [("TFETI", ["--cluster-size", 1]),
                             ("clusters of 8 from the parts",
                              ["--cluster-size", 8, "--cluster-split", "subdomains"]),
                             ("clusters of 8 from the mesh",
                              ["--cluster-size", 8, "--cluster-split", "mesh"])]:
            r = solve([path, "--rtol", 1e-10, *extra], threads=a.threads)
            rows.append({"setting": label, "pcg_iterations": r["matvecs"],
                         "energy": r["objective"], "coarse_dimension": r["coarse_dimension"]})
            print(rows[-1], flush=True)
    print("\n" + save("cluster_split_conditioning.json",
                      {"command": "bench/cluster_split.py --conditioning", "case":
                       "cube 24^3 hex8, 64 METIS parts, own weight, rtol 1e-10", "rows": rows}))
    raise SystemExit(0)


rows, runs = [], []
with tempfile.TemporaryDirectory() as d:
    for name, base, n, cs in CASES:
        path = base
        if n is not None:
            with open(base) as f:
                text = f.read()
            text = re.sub(r"elements = \[\d+, \d+, \d+\]", f"elements = [{n}, {n}, {n}]", text)
            path = os.path.join(d, f"case{n}_{os.path.basename(base)}")
            with open(path, "w") as f:
                f.write(text)
        ref = solve([path, "--rtol", "1e-10", "--cluster-size", 1], threads=a.threads)
        settings = [("TFETI", ["--cluster-size", 1]),
                    ("H-TFETI-DP, clusters from the subdomains",
                     ["--cluster-size", cs, "--cluster-split", "subdomains"]),
                    ("H-TFETI-DP, clusters from the mesh",
                     ["--cluster-size", cs, "--cluster-split", "mesh"])]
        by = {label: [] for label, _ in settings}
        for _ in range(a.repeat):
            for label, extra in settings:  # in turns: a slow minute hits all settings alike
                r = solve([path, *extra], threads=a.threads)
                r.pop("contact", None)
                by[label].append(r)
        for label, extra in settings:
            rs = by[label]
            med = lambda f: statistics.median(f(r) for r in rs)  # noqa: E731
            r = rs[0]
            row = {"case": name, "cluster_size": cs if label != "TFETI" else 1, "setting": label,
                   "clusters": r["clusters"], "coarse_dimension": r["coarse_dimension"],
                   "products": products(r), "outer": r.get("outer_iterations"),
                   "refinements": len(r["solver"].get("accuracy_refinements", [])[1:]),
                   "energy_error": (r["objective"] - ref["objective"]) / abs(ref["objective"]),
                   "setup_s": med(lambda x: x["timings"]["total"] - x["timings"]["solve"]),
                   "solve_s": med(lambda x: x["timings"]["solve"]),
                   "wall_s": med(lambda x: x["wall_seconds"]),
                   "same_bits_over_repeats": len({x["objective"] for x in rs}) == 1}
            rows.append(row)
            runs += rs
            print(row, flush=True)
            save(a.out, {"command": "(partial)", "summary": rows})

print(f"\n{a.threads} threads, medians of {a.repeat}; energy error against TFETI at rtol 1e-10")
print("| case | setting | clusters | coarse dim | products (outer) | refinements | energy error "
      "| setup s | solve s | wall s |")
print("|---|---|---:|---:|---|---:|---:|---:|---:|---:|")
for r in rows:
    outer = f" ({r['outer']})" if r["outer"] else ""
    print(f"| {r['case']} | {r['setting']}{'' if r['setting'] == 'TFETI' else ', ' + str(r['cluster_size'])} "
          f"| {r['clusters']} | {r['coarse_dimension']} | {r['products']}{outer} | "
          f"{r['refinements']} | {r['energy_error']:.1e} | {r['setup_s']:.2f} | "
          f"{r['solve_s']:.2f} | {r['wall_s']:.2f} |")
cmd = "bench/cluster_split.py" + (" --large" if a.large else "") + \
    f" --threads {a.threads} --repeat {a.repeat} --out {a.out}"
print("\n" + save(a.out, {"command": cmd, "summary": rows}))
