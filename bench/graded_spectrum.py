#!/usr/bin/env python3
"""The spectrum that sets the graded Hertz blocks' counts: the extreme eigenvalues of the
preconditioned dual operator as CG sees them (the report's solver.spectrum_estimate and
face_spectrum_estimate, qp/cg_spectrum.hpp), on the four Hertz blocks of bench/hertz_cases.py.

Runs, 16 METIS parts unless the row says otherwise, rtol 1e-4:
- each block under a uniform traction on its top (linear: PCG), lumped and Dirichlet: PCG's
  iterations and the Lanczos estimate of the smallest and largest eigenvalue of P M^-1 P F on
  Ker G;
- each block's contact problem (the rigid sphere) with the automatic settings: Hessian products
  and the face solves' estimate on their faces;
- the strongly graded block under the traction again: with the symmetry planes x = 0 and y = 0
  not held (the bottom alone holds it: no Dirichlet rows on the planes of flat cells next to
  them), with METIS's volume objective instead of the automatic area one, and with 4 to 64
  parts.
Counts and estimates do not depend on the machine's speed.

Usage: bench/graded_spectrum.py [--threads 2] [--out graded_spectrum.json]
Writes bench/results/OUT."""
import argparse
import tempfile

from common import machine, save, solve
from hertz_cases import contact_problems

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--threads", type=int, default=2)
p.add_argument("--out", default="graded_spectrum.json")
a = p.parse_args()

LINEAR = '[[load]]\ngroup = "top"\ntraction = [0.0, 0.0, -1.0]\n'
SYMMETRY = ('[[dirichlet]]\ngroup = "x0"\ncomponents = ["x"]\n',
            '[[dirichlet]]\ngroup = "y0"\ncomponents = ["y"]\n')


def linear_file(toml, path, symmetry=True):
    """The contact problem file `toml` with the sphere replaced by a uniform traction."""
    with open(toml) as f:
        t = f.read()
    t = t[:t.index("[[contact]]")] + LINEAR
    if not symmetry:
        for s in SYMMETRY:
            t = t.replace(s, "")
    with open(path, "w") as f:
        f.write(t)
    return path


def estimate(e):
    return {"min": e["min"], "max": e["max"], "ratio": e["ratio"]} if e else None


rows = []


def run(case, label, args):
    r = solve(args, threads=a.threads)
    s = r["solver"]
    key = "spectrum_estimate" if s["algorithm"] == "pcg" else "face_spectrum_estimate"
    row = {"case": case, "mesh": label, "args": [str(x) for x in args[1:]],
           "preconditioner": r["preconditioner"], "subdomains": r["subdomains"],
           "partition_objective": r.get("partition_objective"), "products": r["matvecs"],
           "estimate": estimate(s.get(key))}
    rows.append(row)
    e = row["estimate"]
    print(f"{case:34s} {label:36s} {row['preconditioner']:9s} {' '.join(row['args']):34s} "
          f"{row['products']:4d} products, eigenvalues "
          + (f"[{e['min']:.3g}, {e['max']:.4g}]" if e else "-"), flush=True)


with tempfile.TemporaryDirectory() as tmp:
    problems = contact_problems(tmp)
    for i, (label, toml) in enumerate(problems):
        lin = linear_file(toml, f"{tmp}/linear{i}.toml")
        for pre in ("lumped", "dirichlet"):
            run("linear", label, [lin, "--preconditioner", pre])
        run("contact", label, [toml])
    label, toml = problems[0]
    lin = f"{tmp}/linear0.toml"
    free = linear_file(toml, f"{tmp}/linear0_free.toml", symmetry=False)
    for pre in ("lumped", "dirichlet"):
        run("linear, no symmetry planes held", label, [free, "--preconditioner", pre])
    run("linear, METIS volume objective", label, [lin, "--partition-objective", "volume"])
    for k in (4, 8, 32, 64):
        run("linear, parts", label, [lin, "--subdomains", k])
save(a.out, {"threads": a.threads, "rows": rows, "machine": machine()})
