#!/usr/bin/env python3
"""SMALBE-M's face solve (qp/face_cg.hpp, docs/method.md "The face solve") on and off, on one
build: Hessian products, outer iterations, face solves (taken, converged), accuracy
refinements, the solve phase's wall time and the energy's distance from a reference solved at
rtol 1e-9 with the face solve off (so the reference does not depend on it).

Cases: the graded Hertz blocks of bench/graded_hertz.py (hex8 strong and mild grading, uniform
hex8, tet4 from a size field; 16 METIS parts; the strong one also at rtol 1e-5), the 40^3 cube-obstacle of issue 32 split as a box
(4 x 4 x 4) and by METIS (64 parts) at A = 1 and A = 20, the same METIS parts in clusters of 8
(A = 1), and the contact examples. --slow adds the 80^3 cube-obstacle in 512 METIS parts at
A = 1 and A = 20 (several minutes each; no reference, the energies of the two runs are compared
with each other). 1 rank x 2 threads, one run each: the counts are what is compared; the times
are single runs.

Usage: bench/face_solve.py [--slow] [--only TEXT] [--out face_solve.json]   (needs gmsh)
(--slow --only 80^3 runs the two 80^3 cases alone.)
Writes bench/results/OUT and prints a markdown table."""
import argparse
import math
import os
import tempfile

from common import BIN, ROOT, machine, save, solve
from hertz_cases import contact_problems

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--slow", action="store_true", help="also the 80^3 cube in 512 METIS parts")
p.add_argument("--only", default="", help="only the cases whose label contains this")
p.add_argument("--threads", type=int, default=2)
p.add_argument("--out", default="face_solve.json")
a = p.parse_args()

CASES = os.path.join(ROOT, "bench", "cases")
EXAMPLES = os.path.join(ROOT, "examples")


def run(args):
    r = solve(args, threads=a.threads, binary=BIN)
    s = r["solver"]
    return {"products": r["matvecs"], "outer": r["outer_iterations"], "converged": r["converged"],
            "face_solves": s.get("face_solves", 0), "face_converged": s.get("face_converged", 0),
            "face_iterations": s.get("face_iterations", 0),
            "refinements": len(s.get("accuracy_refinements", [])),
            "gluing_over_rtol": r["kkt"]["relative_equality_residual"] / r["rtol"],
            "energy": r["objective"], "solve_s": r["timings"]["solve"]}


def amplitude(path, factor, tmp, name):
    with open(path) as f:
        text = f.read()
    for old in ('gap = "sin(pi*x/50)"', 'gap = "1.0*sin(pi*x/50)"'):
        text = text.replace(old, f'gap = "{factor}*sin(pi*x/50)"')
    out = os.path.join(tmp, name)
    with open(out, "w") as f:
        f.write(text)
    return out


rows = []
references = {}  # reference energy by the case's arguments without --rtol
with tempfile.TemporaryDirectory() as tmp:
    cases = []
    for i, (label, toml) in enumerate(contact_problems(tmp)):
        cases.append((label, [toml], True))
        if i == 0:  # the strong grading also at rtol 1e-5 (accuracy against products)
            cases.append((label + ", rtol 1e-5", [toml, "--rtol", "1e-5"], True))
    metis = os.path.join(CASES, "cube40_metis64.toml")
    for A in (1, 20):
        t = amplitude(metis, A, tmp, f"a{A}.toml")
        cases.append((f"cube-obstacle 40^3, A = {A}, box 4 x 4 x 4", [t, "--subdomains", "4,4,4"],
                      True))
        cases.append((f"cube-obstacle 40^3, A = {A}, 64 METIS parts", [t], True))
    cases.append(("cube-obstacle 40^3, A = 1, clusters of 8 METIS parts",
                  [metis, "--cluster-size", "8", "--cluster-split", "subdomains"], True))
    for ex in ("cube-obstacle", "cylinder-on-block", "sphere-on-block", "punch-on-block",
               "friction-block", "friction-block-3d", "membranes", "membranes-two-bodies",
               "bracket"):
        cases.append((f"examples/{ex}.toml", [os.path.join(EXAMPLES, ex + ".toml")], True))
    if a.slow:
        c80 = os.path.join(CASES, "cube80_metis512.toml")
        for A in (1, 20):
            cases.append((f"cube-obstacle 80^3, A = {A}, 512 METIS parts",
                          [amplitude(c80, A, tmp, f"b{A}.toml")], False))
    for label, args, reference in [c for c in cases if a.only in c[0]]:
        row = {"case": label}
        for name, flag in (("off", "--no-face-solve"), ("on", "--face-solve")):
            row[name] = run([*args, flag])
        base = [v for i, v in enumerate(args)
                if v != "--rtol" and (i == 0 or args[i - 1] != "--rtol")]
        key = " ".join(base)
        if reference and key not in references:
            references[key] = solve([*base, "--rtol", "1e-9", "--no-face-solve"],
                                    threads=a.threads, binary=BIN)["objective"]
        ref = references[key] if reference else row["off"]["energy"]
        row["reference_energy"] = ref
        for name in ("off", "on"):
            row[name]["energy_error"] = abs(row[name]["energy"] - ref) / max(abs(ref), 1e-300)
        rows.append(row)
        print(label, row["off"]["products"], row["on"]["products"], flush=True)

print("| case | products off / on | face solves (converged) | solve s off / on |"
      " energy error off / on | gluing / rtol off / on |")
print("|---|---|---|---|---|---|")
for r in rows:
    f, o = r["off"], r["on"]
    print(f"| {r['case']} | {f['products']} / {o['products']} | {o['face_solves']} "
          f"({o['face_converged']}) | {f['solve_s']:.2f} / {o['solve_s']:.2f} | "
          f"{f['energy_error']:.1e} / {o['energy_error']:.1e} | "
          f"{f['gluing_over_rtol']:.2f} / {o['gluing_over_rtol']:.2f} |")
ratios = [r["on"]["products"] / r["off"]["products"] for r in rows]
gm = math.exp(sum(map(math.log, ratios)) / len(ratios))
print(f"geometric mean of on / off products: {gm:.3f}")
save(a.out, {"binary": BIN, "threads": a.threads, "rows": rows, "geometric_mean_ratio": gm,
             "machine": machine()})
