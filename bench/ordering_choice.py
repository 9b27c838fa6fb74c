#!/usr/bin/env python3
"""The fill-reducing ordering of 3D subdomain factors: METIS's nested dissection (METIS_NodeND,
`--ordering metis`) against CHOLMOD's (`--ordering nesdis`: METIS's vertex separators down to
parts of 200 rows, constrained AMD within them), on the meshes users bring: METIS-split cubes,
the graded Hertz blocks (hex8 and tet4) and the tet4 bracket.

Per case and ordering (the runs take turns, ordering by ordering, so that a shared machine's
drift falls on both alike): the factors' size (the report's memory.distinct_factor_mb, MB in
double), the symbolic and numeric factorization in core-seconds (factorization.symbolic_core_s,
numeric_core_s: ordering and analysis, then the numeric factorization, summed over the
subdomains), the factorization phase and the report's total in seconds, the milliseconds per
application of F, the Hessian products and the energy. Sizes and counts do not depend on the
machine; times are medians of --repeat runs.

Cases (--cases, default all but metis80a20):
  metis40      bench/cases/cube40_metis64.toml (A = 1);   metis40a20  the same at A = 20;
  hertz_hex    the strongly graded Hertz block, hex8;     hertz_tet   the tet4 Hertz block;
  bracket      examples/bracket.toml (tet4);              metis80a20  cube80_metis512_a20.toml
                                                                      (about a minute a run).

Usage: bench/ordering_choice.py [--cases ...] [--repeat 3] [--threads 2]
                                [--out ordering_choice.json]"""
import argparse
import os
import statistics
import tempfile

from common import ROOT, save, solve
import hertz_cases

CASES = ["metis40", "metis40a20", "hertz_hex", "hertz_tet", "bracket", "metis80a20"]
ORDERINGS = ["metis", "nesdis"]
p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--cases", nargs="+", default=CASES[:-1], choices=CASES)
p.add_argument("--repeat", type=int, default=3)
p.add_argument("--threads", type=int, default=2)
p.add_argument("--out", default="ordering_choice.json")
a = p.parse_args()


def row_of(r):
    t, f = r["timings"], r["factorization"]
    return {"ordering": r["ordering"], "factor_mb": r["memory"]["distinct_factor_mb"],
            "symbolic_core_s": f["symbolic_core_s"], "numeric_core_s": f["numeric_core_s"],
            "factorization_s": t["factorization"], "total_s": t["total"],
            "F_ms": 1e3 * t["F"] / max(1, r["F_applications"]), "products": r["matvecs"],
            "energy": r["objective"]}


TIMES = ["symbolic_core_s", "numeric_core_s", "factorization_s", "total_s", "F_ms"]
rows = []
with tempfile.TemporaryDirectory() as d:
    cases = os.path.join(ROOT, "bench", "cases")
    files = {"metis40": os.path.join(cases, "cube40_metis64.toml"),
             "metis40a20": os.path.join(cases, "cube40_metis64_a20.toml"),
             "metis80a20": os.path.join(cases, "cube80_metis512_a20.toml"),
             "bracket": os.path.join(ROOT, "examples", "bracket.toml")}
    if "hertz_hex" in a.cases or "hertz_tet" in a.cases:
        problems = hertz_cases.contact_problems(d)
        files["hertz_hex"], files["hertz_tet"] = problems[0][1], problems[3][1]
    for case in a.cases:
        runs = {o: [] for o in ORDERINGS}
        for _ in range(a.repeat):
            for o in ORDERINGS:
                runs[o].append(row_of(solve([files[case], "--ordering", o], threads=a.threads)))
        for o in ORDERINGS:
            r = dict(runs[o][0], case=case)
            for k in TIMES:
                r[k] = statistics.median(x[k] for x in runs[o])
            rows.append(r)
            print(f"{case} {o}: factors {r['factor_mb']:.1f} MB, symbolic {r['symbolic_core_s']:.2f} "
                  f"core-s, numeric {r['numeric_core_s']:.2f} core-s, factorization "
                  f"{r['factorization_s']:.2f} s, F {r['F_ms']:.1f} ms, {r['products']} products, "
                  f"total {r['total_s']:.2f} s", flush=True)

save(a.out, {"repeat": a.repeat, "threads": a.threads, "rows": rows})
