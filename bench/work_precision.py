#!/usr/bin/env python3
"""Work against precision for SMALBE-M's stopping test: Hessian products against the error of
the result, for two builds, on Table 3 reduced (membranes, N_s = 32, H_s/h = 16, m = 1, 2, 4, 8).

The stopping test changed in issue 28 (||G lambda|| <= rtol ||b|| became ||PFP|| ||G lambda|| <=
rtol ||b||, which is scale-invariant), so the two builds stop at different precisions for the
same rtol and their product counts at one rtol do not compare like with like. This script runs
each build over a ladder of rtol values and records, per run, the products and the errors of the
result against a reference solved at rtol 1e-10 by the after build: the relative energy error,
and the equality residual ||B_E u - c_E|| and the largest contact violation of the run's own
displacements (absolute: one problem per m). A build is better when it reaches a given error with fewer
products.

Usage: bench/work_precision.py --before OLD_BINARY [--after NEW_BINARY] [--ms 1 2 4 8]
       [--rtols 1e-4 3e-5 1e-5 3e-6 1e-6] [--threads 2] [--out work_precision.json]
Writes bench/results/<out> and prints one table per m."""
import argparse

from common import BIN, save, solve

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--before", required=True, help="the binary before the change")
p.add_argument("--after", default=BIN, help="the binary after the change (default build/htfeti)")
p.add_argument("--ms", type=int, nargs="+", default=[1, 2, 4, 8])
p.add_argument("--rtols", type=float, nargs="+", default=[1e-4, 3e-5, 1e-5, 3e-6, 1e-6])
p.add_argument("--hh", type=int, default=16)
p.add_argument("--ns", type=int, default=32)
p.add_argument("--threads", type=int, default=2)
p.add_argument("--out", default="work_precision.json")
a = p.parse_args()

n = a.ns * a.hh
rows = []
for m in a.ms:
    args = ["--problem", "membranes", "-n", n, "--subdomains", a.ns, "-m", m, "--glue", "averages"]
    ref = solve(args + ["--rtol", "1e-10"], threads=a.threads, binary=a.after)
    e_ref = ref["objective"]
    print(f"\nm = {m}: reference energy {e_ref:.15e} (rtol 1e-10, {ref['matvecs']} products, "
          f"stop {ref['stop_reason']})")
    print("| build | rtol | outer | products | energy error | equality residual | violation |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for name, binary in (("before", a.before), ("after", a.after)):
        for rtol in a.rtols:
            r = solve(args + ["--rtol", rtol], threads=a.threads, binary=binary)
            k = r["kkt"] if "kkt" in r else r
            row = {"m": m, "build": name, "rtol": rtol, "outer": r["outer_iterations"],
                   "products": r["matvecs"], "stop_reason": r["stop_reason"],
                   "energy_error": abs(r["objective"] - e_ref) / abs(e_ref),
                   "equality_residual": k.get("equality_residual"),
                   "max_violation": k.get("max_violation")}
            rows.append(row)
            print(f"| {name} | {rtol:g} | {row['outer']} | {row['products']} | "
                  f"{row['energy_error']:.2e} | {row['equality_residual']:.2e} | "
                  f"{row['max_violation']:.2e} |", flush=True)
    rows.append({"m": m, "build": "reference", "energy": e_ref, "products": ref["matvecs"]})
cmd = (f"bench/work_precision.py --before {a.before} --after {a.after} --ms "
       f"{' '.join(map(str, a.ms))} --rtols {' '.join(map(str, a.rtols))} --threads {a.threads}")
print("\n" + save(a.out, {"command": cmd, "runs": rows}))
