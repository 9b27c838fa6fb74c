#!/usr/bin/env python3
"""A tight precision is reached and stops (issue 28): the cases that ran to 200 outer iterations
and exit 3 under the old stopping test (ESPRESO's default cube-obstacle at rtol 1e-9 and 1e-10,
the plate with an inactive contact on its hole at 1e-6 and 1e-10, the same cube with E and the
load x 1e6), and every example at 1e-10. Each run is compared with the undecomposed problem: the
same problem file on one subdomain (no gluing multipliers: the direct factor of the whole K and,
with contact, the small QP of the contact rows alone) at rtol 1e-12. The independent check of
the same kind (a primal-dual active set method on the assembled K) is in the tests
(tests/test_contact3d.cpp, CubeObstacle.MatchesTheActiveSetSolution, energies to 1e-10).

Usage: bench/tight_precision.py [--threads 2] [--out tight_precision.json]
Writes bench/results/OUT and prints one row per case: exit state, outer iterations, products,
the test that stopped it and the energy's relative difference from the undecomposed one."""
import argparse
import os
import re
import tempfile

from common import ROOT, save, solve

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--threads", type=int, default=2)
p.add_argument("--out", default="tight_precision.json")
a = p.parse_args()

CUBE = ["--problem", "cube-obstacle", "--elements", "10,20,10", "--subdomains", "2,4,2"]
PLATE = os.path.join(ROOT, "bench", "cases", "plate_hole_inactive_contact.toml")
EX = lambda name: os.path.join(ROOT, "examples", name + ".toml")  # noqa: E731

# The cube scaled: E and the density x 1e6 (the displacements are the same, the energy 1e6 times
# larger), written as a problem file from the built-in one's parameters (docs/results.md).
tmp = tempfile.mkdtemp()
with open(EX("cube-obstacle")) as f:
    text = f.read()
scaled = os.path.join(tmp, "cube-scaled.toml")


def times_1e6(m):
    return f"{m.group(1)} = {float(m.group(2)) * 1e6!r}"


scaled_text, count = re.subn(r"^(young|density)\s*=\s*([0-9.eE+-]+)", times_1e6, text, flags=re.M)
with open(scaled, "w") as f:
    f.write(scaled_text.replace('"meshes/', f'"{ROOT}/examples/meshes/'))

cases = [  # (name, arguments, rtol, arguments of the undecomposed problem)
    ("cube-obstacle 10x20x10 / 2x4x2", CUBE, 1e-9, None),
    ("cube-obstacle 10x20x10 / 2x4x2", CUBE, 1e-10, None),
    ("plate hole, inactive contact, 16 parts", [PLATE, "--subdomains", 16], 1e-6, [PLATE]),
    ("plate hole, inactive contact, 64 parts", [PLATE, "--subdomains", 64], 1e-6, [PLATE]),
    ("plate hole, inactive contact, 16 parts", [PLATE, "--subdomains", 16], 1e-10, [PLATE]),
    ("plate hole, inactive contact, 64 parts", [PLATE, "--subdomains", 64], 1e-10, [PLATE]),
] + [(f"example {n}", [EX(n)], 1e-10, [EX(n)]) for n in
     ["block3d", "bracket", "cube-obstacle", "heterogeneous", "membranes-coercive", "membranes",
      "plate-with-hole", "poisson2d"]]
if count == 2:
    cases.append(("example cube-obstacle, E and density x 1e6", [scaled], 1e-8, [scaled]))

undecomposed = {}
rows = []
print("| case | rtol | converged | outer | products | stopping test | energy | rel. to undecomposed |")
print("|---|---:|---|---:|---:|---|---:|---:|")
for name, args, rtol, ref_args in cases:
    r = solve([*args, "--rtol", rtol, "--max-it", 200], threads=a.threads)
    if ref_args is None:  # a built-in problem: one subdomain of the same mesh
        ref_args = [x if i != args.index("--subdomains") + 1 else "1,1,1"
                    for i, x in enumerate(args)]
    else:
        ref_args = [*ref_args, "--subdomains", 1, "--cluster-size", 1]
    key = " ".join(map(str, ref_args))
    if key not in undecomposed:
        undecomposed[key] = solve([*ref_args, "--rtol", 1e-12, "--max-it", 1000],
                                  threads=a.threads)
    ref = undecomposed[key]
    s = r["solver"]
    if s["algorithm"] == "pcg":
        test = "PCG ||P r|| <= rtol ||P d||"
    else:
        test = "floor" if s.get("tolerance_set_by") == "round-off floor" else "rtol ||b||"
    rel = abs(r["objective"] - ref["objective"]) / abs(ref["objective"])
    rows.append({"case": name, "rtol": rtol, "converged": r["converged"],
                 "outer_iterations": r["outer_iterations"], "products": r["matvecs"],
                 "tolerance_set_by": test, "energy": r["objective"],
                 "undecomposed_energy": ref["objective"],
                 "undecomposed_converged": ref["converged"], "relative_difference": rel,
                 "kkt": r["kkt"], "arguments": " ".join(map(str, args))})
    print(f"| {name} | {rtol:g} | {r['converged']} | {r['outer_iterations']} | {r['matvecs']} | "
          f"{test} | {r['objective']:.13e} | {rel:.1e} |", flush=True)
print("\n" + save(a.out, {"command": f"bench/tight_precision.py --threads {a.threads}",
                          "runs": rows}))
