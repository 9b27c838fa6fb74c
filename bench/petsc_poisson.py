#!/usr/bin/env python3
"""Linear Poisson side by side with a peer: htfeti against CG + hypre's BoomerAMG (PETSc from
Debian's petsc-dev) on poisson2d (Q1, -Laplace u = 1 on the unit square, u = 0 on the boundary),
both to relative residual 1e-4, on the same machine and cores.

  - PETSc: bench/petsc_poisson.c, KSPCG + PCHYPRE boomeramg with its defaults, the residual
    ||b - A u|| <= 1e-4 ||b|| in the unpreconditioned norm, on --ranks MPI ranks (1 thread each).
  - htfeti: the Table 2 shape (H_s/h = 100), TFETI and H-TFETI-DP, no preconditioner and the
    Dirichlet preconditioner, stopping at ||P(F lambda - d)|| <= 1e-4 ||P d||, 1 rank x --ranks
    threads. (The two stopping tests are not the same quantity; the energies are printed so
    the accuracy reached can be compared: q(u) = 1/2 u'Ku - f'u, lower is more accurate.)

Sizes: --n 2000 (4,004,001 unknowns; 20 x 20 subdomains) and 4500 (20,259,001; 45 x 45).
Wall times are medians of --repeat runs (default 3 for n <= 2000, else 1).

Installs petsc-dev with apt-get if it is missing (as root). Usage:
  bench/petsc_poisson.py [--n 2000 4500] [--ranks 2]
Writes bench/results/petsc_poisson.json and prints a markdown table."""
import argparse
import json
import statistics
import subprocess

from common import env, petsc_program, save, solve

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--n", type=int, nargs="+", default=[2000, 4500])
p.add_argument("--ranks", type=int, default=2)
p.add_argument("--repeat", type=int, default=0, help="0: 3 for n <= 2000, else 1")
a = p.parse_args()

exe = petsc_program("petsc_poisson")


def petsc(n):
    out = subprocess.run(["mpiexec", "-n", str(a.ranks), "--oversubscribe", "--bind-to", "none",
                          exe, "-n", str(n), "-rtol", "1e-4"], check=True, env=env(1),
                         capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


rows = []
for n in a.n:
    rep = a.repeat or (3 if n <= 2000 else 1)
    ns = n // 100
    runs = [petsc(n) for _ in range(rep)]
    r = dict(runs[0], total_s=statistics.median(x["total_s"] for x in runs),
             solve_s=statistics.median(x["solve_s"] for x in runs), code="PETSc CG + BoomerAMG",
             repeat=rep)
    rows.append(r)
    ms = [1] + [m for m in (10, 15) if ns % m == 0 and m < ns]
    for m in ms:
        for pc in ["none", "dirichlet"]:
            reps = [solve(["--problem", "poisson2d", "-n", n, "--subdomains", ns, "-m", m,
                           "--preconditioner", pc], threads=a.ranks) for _ in range(rep)]
            h = reps[0]
            rows.append({"n": n, "unknowns": h["primal_dimension"], "code":
                         f"htfeti {'TFETI' if m == 1 else f'H-TFETI-DP m={m}'}, {pc}",
                         "iterations": h["outer_iterations"], "converged": h["converged"],
                         "total_s": statistics.median(x["timings"]["total"] for x in reps),
                         "solve_s": statistics.median(x["timings"]["solve"] for x in reps),
                         "objective": h["objective"],
                         "peak_rss_mb": h["memory"]["peak_rss_mb_max_rank"], "repeat": rep})

print(f"\npoisson2d, {a.ranks} cores (PETSc: {a.ranks} ranks; htfeti: 1 rank x {a.ranks} threads), "
      "eps = 1e-4\n")
print("| n | unknowns (htfeti: with copies) | code | iterations | solve s | total s | energy |")
print("|---:|---:|---|---:|---:|---:|---:|")
for r in rows:
    print(f"| {r['n']} | {r['unknowns']:,} | {r['code']} | {r['iterations']} | {r['solve_s']:.2f} | "
          f"{r['total_s']:.2f} | {r['objective']:.10e} |")
print("\nwritten:", save("petsc_poisson.json", {"ranks": a.ranks, "runs": rows}))
