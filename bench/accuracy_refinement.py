#!/usr/bin/env python3
"""The accuracy refinement (src/solve_parts.hpp) on the cases that need it: H-TFETI-DP on
clusters of 8 (and 4) METIS parts of the cube of bench/cases (hex8, 64 parts), where the dual
stopping test at rtol 1e-4 leaves the primal gluing residual ||B_E u - c_E|| at 8-72 rtol of
||u|| + ||c_E||. Per case, at rtol 1e-4: the build under test (and --before, a build without the
refinement), their Hessian products, the refinement steps, the gluing residual in units of rtol
and the energy's distance from the reference: TFETI on the same 64 parts at rtol 1e-10.

Cases: the cube under its own weight, clamped at x = 0, at 24^3 and 40^3 (linear: PCG), and the
40^3 cube-obstacle of issue 32 (contact: SMALBE-M). 1 rank x 2 threads, one run each (the
counts are what is compared; the seconds are listed as measured).

Usage: bench/accuracy_refinement.py [--before OLD/htfeti] [--after build/htfeti] [--threads 2]
Writes bench/results/accuracy_refinement.json and prints a markdown table."""
import argparse
import os
import re
import tempfile

from common import BIN, ROOT, machine, save, solve

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--before")
p.add_argument("--after", default=BIN)
p.add_argument("--threads", type=int, default=2)
a = p.parse_args()

CASES = [("cube 24^3, linear", "cube40_metis64_linear.toml", 24, ["--cluster-size", "8"]),
         ("cube 24^3, linear, corners", "cube40_metis64_linear.toml", 24,
          ["--cluster-size", "8", "--glue", "corners"]),
         ("cube 24^3, linear, clusters of 4", "cube40_metis64_linear.toml", 24,
          ["--cluster-size", "4"]),
         ("cube 40^3, linear", "cube40_metis64_linear.toml", 40, ["--cluster-size", "8"]),
         ("cube-obstacle 40^3", "cube40_metis64.toml", 40, ["--cluster-size", "8"])]
builds = [("after", a.after)] + ([("before", a.before)] if a.before else [])
rows = []
with tempfile.TemporaryDirectory() as d:
    for name, base, n, extra in CASES:
        with open(os.path.join(ROOT, "bench", "cases", base)) as f:
            text = f.read()
        text = re.sub(r"elements = \[40, 40, 40\]", f"elements = [{n}, {n}, {n}]", text)
        path = os.path.join(d, f"case{n}.toml")
        with open(path, "w") as f:
            f.write(text)
        ref = solve([path, "--rtol", "1e-10", "--cluster-size", "1"], threads=a.threads)
        row = {"case": name, "args": extra, "reference_energy": ref["objective"],
               "reference": "TFETI, same 64 parts, rtol 1e-10"}
        for label, binary in builds:
            r = solve([path, *extra], threads=a.threads, binary=binary)
            steps = r["solver"].get("accuracy_refinements", [])
            row[label] = {
                "products": r["matvecs"], "outer": r["outer_iterations"],
                "converged": r["converged"],
                "gluing_over_rtol": r["kkt"]["relative_equality_residual"] / r["rtol"],
                "energy_error": abs(r["objective"] - ref["objective"]) / abs(ref["objective"]),
                "refinements": steps, "total_s": r["timings"]["total"],
                "wall_s": r["wall_seconds"]}
        rows.append(row)
        print(row, flush=True)

print("| case | build | products | refinement rtols | gluing / rtol | energy error |")
print("|---|---|---:|---|---:|---:|")
for row in rows:
    for label, _ in builds:
        b = row[label]
        rt = ", ".join(f"{s['rtol']:.1e}" for s in b["refinements"]) or "-"
        print(f"| {row['case']} | {label} | {b['products']} | {rt} | {b['gluing_over_rtol']:.2f} "
              f"| {b['energy_error']:.1e} |")
print(save("accuracy_refinement.json",
           {"command": "bench/accuracy_refinement.py" + (" --before OLD" if a.before else ""),
            "threads": a.threads, "machine": machine(), "rows": rows}))
