#!/usr/bin/env python3
"""The automatic dual operator's cost model (include/htfeti/feti/operator_cost.hpp), fitted and
checked. Each case is solved with `--dual-operator implicit` and `explicit` on one rank and one
thread (the model's constants are one thread's), every subdomain with its own analysis and
factor (`--numeric-cache 0 --symbolic-cache 0`, as on a user's mesh), medians of --repeat runs. From the reports:
the model's counts of the sampled subdomains (`dual_operator_model.sample_mean`), and per
subdomain the measured seconds of the factorization phase (for the explicit operator it includes
forming the F_i) and of one F (`timings.F / F_applications`).

The constants are fitted on the TFETI cases (--fit), each pair by least squares of the relative
errors: c_factor and c_unknown, the implicit factorization phase on the factor's flops and the
unknowns (ordering, analysis, K_rr); c_dense and c_explicit_unknown, the explicit phase's excess
over it on n_b^3 and the unknowns (the interface-last ordering); c_sweep and c_supernode, the
implicit F on 16 * values and supernodes; c_packed = median of explicit F / bytes(F_i). Every case, H-TFETI-DP included, then shows the
model's seconds against the measured ones, its break-even count of F applications, the measured
break-even, the operator the model prefers at the expected applications, and which operator
was faster on the case's own applications. Without --fit the constants are the program's
(OperatorCostConstants::fitted), so a rerun checks them.

Usage: bench/operator_cost.py [--repeat 3] [--fit] [--from EARLIER.json] [--out operator_cost.json]"""
import argparse
import os
import statistics

from common import ROOT, machine, save, solve

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--repeat", type=int, default=3)
p.add_argument("--fit", action="store_true", help="fit the constants (else the program's)")
p.add_argument("--out", default="operator_cost.json")
p.add_argument("--from", dest="source", help="the measurements of an earlier run's JSON (no runs)")
a = p.parse_args()

EX = os.path.join(ROOT, "examples")
# Every subdomain analysed and factored on its own, as on a user's mesh: the equal subdomains of
# a generated box share their analysis and factor otherwise (which makes the implicit operator
# cheaper still, in setup and, reading one factor for many, per F; the model does not count it).
OWN = ["--numeric-cache", "0", "--symbolic-cache", "0"]
TFETI = ["--cluster-size", "1"]
CASES = [  # (name, arguments, used for the fit)
    ("2D membranes 16^2 x 32 (Table 3 reduced)",
     ["--problem", "membranes", "-n", 512, "--subdomains", 32, "-m", 1], True),
    ("2D membranes 64^2 x 8", ["--problem", "membranes", "-n", 512, "--subdomains", 8, "-m", 1],
     True),
    ("2D poisson 16^2 x 16", ["--problem", "poisson2d", "-n", 256, "--subdomains", 16], True),
    ("2D poisson 128^2 x 8", ["--problem", "poisson2d", "-n", 1024, "--subdomains", 8], True),
    ("2D plate-with-hole, METIS 16", [os.path.join(EX, "plate-with-hole.toml"), *TFETI], True),
    ("3D cube-obstacle 4^3 x 8", ["--problem", "cube-obstacle", "--elements", "8,8,8",
                                  "--subdomains", "2,2,2"], True),
    ("3D cube-obstacle 6^3 x 64", ["--problem", "cube-obstacle", "--elements", 24,
                                   "--subdomains", 4, *TFETI], True),
    ("3D cube-obstacle 10^3 x 64 (Table 4 1x1x1)",
     ["--problem", "cube-obstacle", "--preconditioner", "none", "--elements", 40,
      "--subdomains", 4, *TFETI], True),
    ("3D cube 40^3, METIS 64", [os.path.join(ROOT, "bench", "cases", "cube40_metis64.toml")],
     True),
    ("3D bracket (tet4), METIS 12", [os.path.join(EX, "bracket.toml"), *TFETI], True),
    ("2D membranes 16^2 x 32, H-TFETI-DP m = 4",
     ["--problem", "membranes", "-n", 512, "--subdomains", 32, "-m", 4], False),
    ("3D Table 4 1x1x1 H-TFETI-DP",
     ["--problem", "cube-obstacle", "--preconditioner", "none", "--elements", 40,
      "--subdomains", 4, "--cluster-size", 4], False),
]

# The program's constants (OperatorCostConstants::fitted, src/feti/operator_cost.cpp).
PROGRAM = {"sweep": 1.04e-10, "supernode": 6.13e-7, "packed": 1.61e-10, "factor": 2.09e-10,
           "unknown": 2.92e-6, "dense": 1.24e-10, "explicit_unknown": 1.33e-6}

rows = []
if a.source:
    import json
    with open(a.source) as f:
        rows = json.load(f)["rows"]
for name, args, fit in [] if a.source else CASES:
    row = {"case": name, "fit": fit}
    for op in ("implicit", "explicit"):
        runs = [solve([*args, *OWN, "--dual-operator", op], threads=1) for _ in range(a.repeat)]
        r = runs[0]
        S = r["subdomains"]
        med = lambda f: statistics.median(f(x) for x in runs)  # noqa: E731
        row[op] = {"products": r["matvecs"], "F_applications": r["F_applications"],
                   "factorization_s": med(lambda x: x["timings"]["factorization"]) / S,
                   "F_s": med(lambda x: x["timings"]["F"] / x["F_applications"]) / S,
                   "total_s": med(lambda x: x["timings"]["total"])}
        row["subdomains"] = S
        if op == "implicit":
            model = r.get("dual_operator_model")
            if model is None:  # a requested operator: the model did not run; ask auto for it
                model = solve([*args, *OWN, "--dual-operator", "auto"],
                              threads=1)["dual_operator_model"]
            row["sample"] = model["sample_mean"]
            row["expected_applications"] = model["expected_applications"]
    print(name, row["implicit"], row["explicit"], flush=True)
    rows.append(row)


def units(row):
    m = row["sample"]
    mult = m["multipliers"]
    return {"values16": 16 * m["factor_values"], "supernodes": m["factor_supernodes"],
            "packed": 8 * mult * (mult + 1) / 2, "flops": m["factor_flops"],
            "dense": m["interface_dofs"] ** 3}


fitting = [r for r in rows if r["fit"]]


def least_squares(pairs, b):
    """x >= 0 (2 entries) minimizing the sum of ((x0 u + x1 v) / b - 1)^2: the 2 x 2 normal
    equations of the relative errors; an entry that comes out negative is dropped."""
    A = [(u / t, v / t) for (u, v), t in zip(pairs, b)]
    s11 = sum(x * x for x, _ in A)
    s12 = sum(x * y for x, y in A)
    s22 = sum(y * y for _, y in A)
    t1, t2 = sum(x for x, _ in A), sum(y for _, y in A)
    det = s11 * s22 - s12 * s12
    x = [(t1 * s22 - t2 * s12) / det, (s11 * t2 - s12 * t1) / det]
    if x[1] < 0:
        x = [t1 / s11, 0.0]
    if x[0] < 0:
        x = [0.0, t2 / s22]
    return x


if a.fit:
    c = {}
    n = [r["sample"]["unknowns"] for r in fitting]
    c["factor"], c["unknown"] = least_squares(
        [(units(r)["flops"], m) for r, m in zip(fitting, n)],
        [r["implicit"]["factorization_s"] for r in fitting])
    c["dense"], c["explicit_unknown"] = least_squares(
        [(units(r)["dense"], m) for r, m in zip(fitting, n)],
        [r["explicit"]["factorization_s"] - r["implicit"]["factorization_s"] for r in fitting])
    c["sweep"], c["supernode"] = least_squares(
        [(units(r)["values16"], units(r)["supernodes"]) for r in fitting],
        [r["implicit"]["F_s"] for r in fitting])
    c["packed"] = statistics.median(r["explicit"]["F_s"] / units(r)["packed"] for r in fitting)
else:
    c = PROGRAM

print("\nconstants (seconds per unit, one thread):", {k: f"{v:.3g}" for k, v in c.items()})
print("\n| case | S | n_i | m | n_b | implicit setup s model / measured | implicit F ms model / "
      "measured | explicit setup s model / measured | explicit F ms model / measured | "
      "break-even model / measured | F applications | model prefers | faster on the case |")
print("|---|---:|---:|---:|---:|---|---|---|---|---|---:|---|---|")
for r in rows:
    u = units(r)
    mi_set = c["factor"] * u["flops"] + c["unknown"] * r["sample"]["unknowns"]
    mi_F = c["sweep"] * u["values16"] + c["supernode"] * u["supernodes"]
    me_set = mi_set + c["dense"] * u["dense"] + c["explicit_unknown"] * r["sample"]["unknowns"]
    me_F = c["packed"] * u["packed"]
    be_model = (me_set - mi_set) / (mi_F - me_F) if mi_F > me_F else float("inf")
    I, E = r["implicit"], r["explicit"]
    dF = I["F_s"] - E["F_s"]
    be_meas = (E["factorization_s"] - I["factorization_s"]) / dF if dF > 0 else float("inf")
    N = r["expected_applications"]
    prefers = "explicit" if be_model <= N else "implicit"
    faster = "explicit" if E["total_s"] < I["total_s"] else "implicit"
    r["model"] = {"implicit_setup_s": mi_set, "implicit_F_s": mi_F, "explicit_setup_s": me_set,
                  "explicit_F_s": me_F, "break_even": be_model, "prefers": prefers}
    r["measured_break_even"] = be_meas
    r["faster"] = faster
    m = r["sample"]
    print(f"| {r['case']} | {r['subdomains']} | {m['unknowns']:.0f} | {m['multipliers']:.0f} | "
          f"{m['interface_dofs']:.0f} | {mi_set:.2e} / {I['factorization_s']:.2e} | "
          f"{1e3 * mi_F:.3f} / {1e3 * I['F_s']:.3f} | {me_set:.2e} / {E['factorization_s']:.2e} | "
          f"{1e3 * me_F:.3f} / {1e3 * E['F_s']:.3f} | {be_model:.1f} / {be_meas:.1f} | "
          f"{I['F_applications']} | {prefers} | {faster} ({I['total_s']:.2f} / "
          f"{E['total_s']:.2f} s) |")
cmd = f"bench/operator_cost.py --repeat {a.repeat}" + (" --fit" if a.fit else "") + (
    f" --from {a.source}" if a.source else "")
print("\n" + save(a.out, {"command": cmd, "machine": machine(), "constants": c, "rows": rows}))
