#!/usr/bin/env python3
"""SMALBE-M's parameters measured over the benchmark set (issue 28): the penalty rho = rho_factor
||PFP||, the initial bound M_0 = M0_factor ||PFP||, eta = eta_factor ||b|| and the late penalty
factor rho_update_late (smalbe.hpp, step 4), over the contact
cases of Table 3 reduced (membranes, H_s/h = 16, m = 1, 2, 4, 8), the Table 4 row 1x1x1 (TFETI
and H-TFETI-DP, no preconditioner, as in the table), the contact examples, the cube-obstacle
with partial contact (amplitude 20), ESPRESO's default cube at rtol 1e-10 and the plate with an
inactive contact at rtol 1e-6; with --metis also the cube-obstacle at 40^3 split by METIS into
64 parts (volume and cut objective, issue 32; and in clusters of 8, split from the mesh) and
the contact pairs cylinder-, sphere- and
punch-on-block; with --hertz the four graded Hertz blocks (bench/hertz_cases.py, needs gmsh);
with --friction the friction examples (2D Tresca, 3D Coulomb) and the Table 4 cube-obstacle
1x1x1 with Coulomb friction (bench/table4_friction.py's problem, TFETI and H-TFETI-DP).
Robustness first: a setting is ranked by its failures (not converged within 200
outer iterations), then by the geometric mean over the cases of its Hessian products relative
to a fixed baseline's, the defaults of issue 28 (rho 1.1, M_0 100, eta 0.1, late factor 2, the
power method; M_0 = 1 and Lanczos are the defaults now); with
--norm-estimate the products of the norm estimate count too (they cost as much).

Usage: bench/smalbe_sweep.py [--rho 1.1 3] [--M0 1 10 100] [--eta 0.01 0.1 1] [--late 2]
       [--norm-estimate power lanczos] [--metis] [--hertz] [--friction] [--threads 2]
       [--out smalbe_sweep.json]
Writes bench/results/OUT and prints the settings best first."""
import argparse
import itertools
import math
import tempfile

from common import save, solve
from contact_cases import contact_cases

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--rho", type=float, nargs="+", default=[1.1, 3.0])
p.add_argument("--M0", type=float, nargs="+", default=[1.0, 10.0, 100.0])
p.add_argument("--eta", type=float, nargs="+", default=[0.01, 0.1, 1.0])
p.add_argument("--late", type=float, nargs="+", default=[2.0])
p.add_argument("--norm-estimate", nargs="+", default=None)
p.add_argument("--metis", action="store_true")
p.add_argument("--hertz", action="store_true")
p.add_argument("--friction", action="store_true")
p.add_argument("--threads", type=int, default=2)
p.add_argument("--out", default="smalbe_sweep.json")
a = p.parse_args()

tmp = tempfile.TemporaryDirectory()  # removed at exit
CASES = contact_cases(tmp.name, metis=a.metis, hertz=a.hertz, friction=a.friction)
norms = a.norm_estimate or ["power"]
count_norm = a.norm_estimate is not None
settings = list(itertools.product(a.rho, a.M0, a.eta, a.late, norms))
default = (1.1, 100.0, 0.1, 2.0, "power")  # the baseline (see above), always run
if default not in settings:
    settings.insert(0, default)
results = {}
for rho, M0, eta, late, norm in settings:
    runs = []
    for name, args in CASES:
        r = solve([*args, "--rho-factor", rho, "--M0-factor", M0, "--eta-factor", eta,
                   "--rho-update-late", late, "--norm-estimate", norm, "--max-it", 200],
                  threads=a.threads)
        norm_products = r["solver"].get("norm_estimate_matvecs", 0)
        runs.append({"case": name, "converged": r["converged"],
                     "outer_iterations": r["outer_iterations"], "products": r["matvecs"],
                     "norm_estimate_products": norm_products,
                     "cost": r["matvecs"] + (norm_products if count_norm else 0),
                     "energy": r["objective"]})
    results[(rho, M0, eta, late, norm)] = runs
    fails = sum(not x["converged"] for x in runs)
    print(f"rho {rho:g} M0 {M0:g} eta {eta:g} late {late:g} {norm}: {fails} failures, "
          f"products {' '.join(str(x['cost']) for x in runs)}", flush=True)

base = {x["case"]: x["cost"] for x in results[default]}
rows = []
for key, runs in results.items():
    fails = sum(not x["converged"] for x in runs)
    gm = math.exp(sum(math.log(x["cost"] / base[x["case"]]) for x in runs) / len(runs))
    rows.append({"rho_factor": key[0], "M0_factor": key[1], "eta_factor": key[2],
                 "rho_update_late": key[3], "norm_estimate": key[4],
                 "failures": fails, "relative_products_geomean": gm,
                 "total_products": sum(x["cost"] for x in runs), "runs": runs})
rows.sort(key=lambda r: (r["failures"], r["relative_products_geomean"]))
print("\n| rho_factor | M0_factor | eta_factor | late | norm estimate | failures | products / "
      "default's (geo. mean) | total products |")
print("|---:|---:|---:|---:|---|---:|---:|---:|")
for r in rows:
    print(f"| {r['rho_factor']:g} | {r['M0_factor']:g} | {r['eta_factor']:g} | "
          f"{r['rho_update_late']:g} | {r['norm_estimate']} | {r['failures']} | "
          f"{r['relative_products_geomean']:.3f} | {r['total_products']} |")
cmd = (f"bench/smalbe_sweep.py --rho {' '.join(map(str, a.rho))} --M0 {' '.join(map(str, a.M0))}"
       f" --eta {' '.join(map(str, a.eta))} --late {' '.join(map(str, a.late))}"
       f" --norm-estimate {' '.join(norms)}{' --metis' if a.metis else ''}"
       f"{' --hertz' if a.hertz else ''}{' --friction' if a.friction else ''}"
       f" --threads {a.threads}")
print("\n" + save(a.out, {"command": cmd, "cases": [c[0] for c in CASES], "settings": rows}))
