#!/usr/bin/env python3
"""Table 4's small rows with Coulomb friction: the cube-obstacle (examples/cube-obstacle.toml,
the built-in problem as a problem file: hex8 on [0, 100]^3, clamped on x = 0, own weight, the
obstacle u_z >= -sin(pi x / 50) on z = 0) with friction = { law = "coulomb", coefficient = mu }
on the contact, clusters of 4 x 4 x 4 subdomains at H_s/h = 10, k x k x k clusters, TFETI
against H-TFETI-DP (face averages), SMALBE-M with MPGP (discs) inside at eps = 1e-4, the Coulomb
fixed point to max(1e-6, 10 eps) = 1e-3. The frictionless problem is run beside it.

Usage: bench/table4_friction.py [--ks 1 2] [--mu 0.3] [--threads 2] [--out table4_friction.json]
Writes bench/results/OUT."""
import argparse
import os
import tempfile

from common import save, solve
from table4_friction_problem import PROBLEM


p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--ks", type=int, nargs="+", default=[1, 2])
p.add_argument("--mu", type=float, default=0.3)
p.add_argument("--threads", type=int, default=2)
p.add_argument("--out", default="table4_friction.json")
a = p.parse_args()
rows = []
print(f"cube-obstacle, clusters of 4^3 subdomains, H_s/h = 10, Coulomb mu = {a.mu}, "
      f"1 rank x {a.threads} threads")
print("| clusters | subdomains | unknowns | method | friction | outer | products | Coulomb solves "
      "| stick / slip nodes | tangential force x | solve s | total s |")
print("|---|---:|---:|---|---|---:|---:|---:|---|---:|---:|---:|")
with tempfile.TemporaryDirectory() as tmp:
    for k in a.ks:
        s, n = 4 * k, 40 * k
        for method, m in (("TFETI", 1), ("H-TFETI-DP", 4)):
            for friction in ("none", "coulomb"):
                text = PROBLEM.format(n=n, s=s, m=m, friction=(
                    f'friction = {{ law = "coulomb", coefficient = {a.mu} }}'
                    if friction == "coulomb" else ""))
                path = os.path.join(tmp, f"c{k}{m}{friction}.toml")
                with open(path, "w") as f:
                    f.write(text)
                r = solve([path], threads=a.threads)
                c = r["contact_summary"][0]
                row = {"k": k, "subdomains": r["subdomains"], "unknowns": r["primal_dimension"],
                       "method": method, "friction": friction, "outer": r["outer_iterations"],
                       "products": r["matvecs"], "converged": r["converged"],
                       "coulomb_solves": r["solver"].get("coulomb", {}).get("solves", 0),
                       "stick": c.get("stick_nodes"), "slip": c.get("slip_nodes"),
                       "tangential_x": c["tangential_force"][0] if "tangential_force" in c else None,
                       "solve_s": r["timings"]["solve"], "total_s": r["timings"]["total"]}
                rows.append(row)
                tx = f"{row['tangential_x']:.4g}" if row["tangential_x"] is not None else "-"
                ss = f"{row['stick']} / {row['slip']}" if row["stick"] is not None else "-"
                print(f"| {k}x{k}x{k} | {row['subdomains']} | {row['unknowns']} | {method} | "
                      f"{friction} | {row['outer']} | {row['products']} | {row['coulomb_solves']} | "
                      f"{ss} | {tx} | {row['solve_s']:.1f} | {row['total_s']:.1f} |", flush=True)
                save(a.out, {"command": "(partial)", "rows": rows})
print(save(a.out, {"command": f"bench/table4_friction.py --ks {' '.join(map(str, a.ks))} "
                              f"--mu {a.mu}", "rows": rows}))
