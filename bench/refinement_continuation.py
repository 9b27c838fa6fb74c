#!/usr/bin/env python3
"""SMALBE-M's accuracy refinement on the contact cases that need one, from two builds side by
side: the Hessian products, the refinement steps (rtol asked, gluing residual in units of the
first rtol) and the energy's distance from a reference solved at rtol 1e-9 (the --after build,
no refinement needed there). Written for the change that makes the refinement continue the last
SMALBE-M solve (its rho and M) instead of restarting them from rho_0 and M_0 (docs/method.md,
"Accuracy refinement").

Cases: the graded Hertz blocks of bench/graded_hertz.py (contact, 16 METIS parts, the automatic
partition objective: hex8 strong and mild grading, uniform hex8, tet4 from a size field), and
the 40^3 cube-obstacle split into 64 METIS parts grouped into clusters of 8
(`--cluster-split subdomains`) at A = 1 (and with --slow also A = 20, about 2.5 minutes per
build). 1 rank x 2 threads, one run each: the counts are what is compared.

Usage: bench/refinement_continuation.py --before OLD/htfeti [--after build/htfeti] [--slow]
                                        [--out refinement_continuation.json]   (needs gmsh)
Writes bench/results/OUT and prints a markdown table."""
import argparse
import math
import os
import tempfile

from common import BIN, ROOT, machine, save, solve
from hertz_cases import contact_problems

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--before", required=True)
p.add_argument("--after", default=BIN)
p.add_argument("--slow", action="store_true", help="also the A = 20 cube in clusters")
p.add_argument("--threads", type=int, default=2)
p.add_argument("--out", default="refinement_continuation.json")
a = p.parse_args()

CUBE = os.path.join(ROOT, "bench", "cases", "cube40_metis64.toml")
CLUSTERS = ["--cluster-size", "8", "--cluster-split", "subdomains"]


def run(binary, args):
    r = solve(args, threads=a.threads, binary=binary)
    steps = r["solver"].get("accuracy_refinements", [])
    return {"products": r["matvecs"], "outer": r["outer_iterations"], "converged": r["converged"],
            "refinements": [[s["rtol"], s["gluing_residual_over_rtol"]] for s in steps],
            "energy": r["objective"], "solve_s": r["timings"]["solve"]}


rows = []
with tempfile.TemporaryDirectory() as tmp:
    cases = []
    for label, toml in contact_problems(tmp):
        cases.append((label, [toml]))
    cases.append(("cube-obstacle 40^3, A = 1, clusters of 8 METIS parts", [CUBE, *CLUSTERS]))
    if a.slow:
        with open(CUBE) as f:
            text = f.read().replace('gap = "sin(pi*x/50)"', 'gap = "20*sin(pi*x/50)"')
        toml = os.path.join(tmp, "a20.toml")
        with open(toml, "w") as f:
            f.write(text)
        cases.append(("cube-obstacle 40^3, A = 20, clusters of 8 METIS parts", [toml, *CLUSTERS]))
    for label, args in cases:
        ref = solve([*args, "--rtol", "1e-9"], threads=a.threads, binary=a.after)["objective"]
        row = {"case": label, "reference_energy": ref}
        for name, binary in (("before", a.before), ("after", a.after)):
            row[name] = run(binary, args)
            row[name]["energy_error"] = abs(row[name]["energy"] - ref) / abs(ref)
        rows.append(row)
        print(label, row["before"]["products"], row["after"]["products"], flush=True)

print("| case | products before / after | refinements before | refinements after |"
      " energy error before / after |")
print("|---|---|---|---|---|")
fmt = lambda s: ", ".join(f"{r:.2g} ({g:.2f})" for r, g in s[1:]) or "-"
for r in rows:
    b, f = r["before"], r["after"]
    print(f"| {r['case']} | {b['products']} / {f['products']} | {fmt(b['refinements'])} | "
          f"{fmt(f['refinements'])} | {b['energy_error']:.1e} / {f['energy_error']:.1e} |")
ratios = [r["after"]["products"] / r["before"]["products"] for r in rows]
gm = math.exp(sum(map(math.log, ratios)) / len(ratios))
print(f"geometric mean of after / before products: {gm:.3f}")
save(a.out, {"before": a.before, "after": a.after, "threads": a.threads, "rows": rows,
             "geometric_mean_ratio": gm, "machine": machine()})
