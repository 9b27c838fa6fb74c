#!/usr/bin/env python3
"""How far round-off moves the iteration counts (issue 28): Table 3 reduced (membranes,
H_s/h = 16, m = 1, 2, 4, 8) and the Table 4 rows 1x1x1 and 2x2x2 (cube-obstacle, clusters of
4 x 4 x 4 subdomains at H_s/h = 10, TFETI and H-TFETI-DP), each solved with the load as given
and with every load entry times 1 + delta r (`--perturb-load delta`, r in [-1, 1] fixed by the
dof's global number) for delta = +-1e-14 and 3e-14. The solution moves by about delta; a robust
solver's outer iterations and Hessian products move by little. Reports per case the counts and
the spread (max - min) / min of each.

Usage: bench/perturbation.py [--deltas 0 1e-14 -1e-14 3e-14] [--table4-ks 1 2] [--threads 2]
       [--extra "more htfeti solve arguments"] [--out perturbation.json]
Writes bench/results/OUT."""
import argparse

from common import save, solve

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--deltas", type=float, nargs="+", default=[0.0, 1e-14, -1e-14, 3e-14])
p.add_argument("--table4-ks", type=int, nargs="*", default=[1, 2])
p.add_argument("--threads", type=int, default=2)
p.add_argument("--extra", default="", help="further htfeti solve arguments, quoted")
p.add_argument("--out", default="perturbation.json")
a = p.parse_args()

cases = [(f"Table 3 reduced m = {m}",
          ["--problem", "membranes", "-n", 512, "--subdomains", 32, "-m", m]) for m in (1, 2, 4, 8)]
for k in a.table4_ks:
    s, n = 4 * k, 40 * k
    for method, m in (("TFETI", 1), ("H-TFETI-DP", 4)):
        cases.append((f"Table 4 {k}x{k}x{k} {method}",
                      ["--problem", "cube-obstacle", "--elements", n, "--subdomains", s,
                       "--cluster-size", m, "--preconditioner", "none"]))

rows = []
print("| case | outer per delta | products per delta | outer spread | products spread | "
      "energy spread |")
print("|---|---|---|---:|---:|---:|")
for name, args in cases:
    outer, prods, energy = [], [], []
    for d in a.deltas:
        r = solve([*args, "--perturb-load", repr(d), *a.extra.split()], threads=a.threads)
        if not r["converged"]:
            print(f"  {name}, delta {d}: NOT converged ({r['stop_reason']})", flush=True)
        outer.append(r["outer_iterations"])
        prods.append(r["matvecs"])
        energy.append(r["objective"])
    spread = lambda v: (max(v) - min(v)) / max(min(v), 1)  # noqa: E731
    e_spread = (max(energy) - min(energy)) / abs(energy[0])
    rows.append({"case": name, "arguments": " ".join(map(str, args)), "deltas": a.deltas,
                 "outer_iterations": outer, "products": prods, "energies": energy,
                 "outer_spread": spread(outer), "products_spread": spread(prods),
                 "energy_spread": e_spread})
    print(f"| {name} | {' / '.join(map(str, outer))} | {' / '.join(map(str, prods))} | "
          f"{spread(outer):.0%} | {spread(prods):.0%} | {e_spread:.1e} |", flush=True)
cmd = "bench/perturbation.py --deltas " + " ".join(map(repr, a.deltas)) + " --table4-ks " + \
      " ".join(map(str, a.table4_ks)) + f" --threads {a.threads}" + \
      (f' --extra "{a.extra}"' if a.extra else "")
print("\n" + save(a.out, {"command": cmd, "runs": rows}))
