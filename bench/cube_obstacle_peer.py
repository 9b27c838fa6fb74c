#!/usr/bin/env python3
"""The cube-obstacle side by side with PETSc's contact solver (issue 32): htfeti on the box split
(equal subdomains, H/h = 10) and on the same cube split by METIS (as a user's mesh is), and the
PETSc peer, in one run on the same machine and cores; writes the ratios.

The problem (../shared/DESIGN.md, examples/cube-obstacle.toml): [0,100]^3, n^3 hex8, E = 2.1e7,
nu = 0.3, own weight, clamped at x = 0, the obstacle u_z >= -A sin(pi x / 50) under z = 0.
  - PETSc: bench/petsc_cube_obstacle.c, the same discrete problem assembled by PETSc (DMDA)
    and solved by SNES VI (reduced-space active-set Newton) with CG + GAMG and the rigid body
    modes as near-null space; -snes_rtol and -ksp_rtol = --rtol; --ranks MPI ranks, 1 thread.
  - htfeti: TFETI (clusters of 1), defaults otherwise, stopping at relative precision --rtol;
    1 rank x --ranks threads. Box split: (n/10)^3 subdomains; METIS split: the same number;
    each also with --mprgp-expansion preconditioned (MPRGP's expansion step along the
    preconditioned free gradient) and projected-cg (the projected CG step; splits
    box_projected_cg and metis_projected_cg, not in the default list) and gradient (the
    fixed-length gradient step, the default before --mprgp-expansion auto; splits box_gradient
    and metis_gradient, not in the default list), and with
    --preconditioner dirichlet (splits box_dirichlet and metis_dirichlet, not in the default
    list), and with --factor-precision double (the factor sweeps in double instead of the
    automatic single-precision copies; splits box_double, metis_double and
    metis_dirichlet_double, not in the default list). The METIS split's parts are made compact
    (--partition-shape compact, the default); split metis_shape keeps METIS's own parts (not in
    the default list).
The two stopping tests are not the same quantity; each row also gives its energy's distance
from the reference energy (the peer's solve at rtol 1e-10), so the accuracy reached can be
compared. --check-energy also solves each case with htfeti at rtol 1e-8 and asserts that its
energy equals the reference to 1e-8 (relative): the two codes solve the same discrete problem.

Wall times: the whole process (mpiexec and start-up included), medians of --repeat runs where a
run takes under a minute, one run above. With --turns K the peer and the htfeti rows are run K
times in turns and each wall time and ratio is the median over the turns (the ratio of each
turn is kept): this host's speed can drift by a quarter within minutes, and the codes taking
turns see the drift alike. The order alternates (odd turns: the peer first; even turns: the
htfeti rows first), since the code that runs second meets the pages the first one freed. Peak RSS: htfeti's report (one rank); the peer's sum
over its ranks (getrusage).

Installs petsc-dev with apt-get if it is missing (as root). Usage:
  bench/cube_obstacle_peer.py [--n 40 80] [--amplitude 1 20] [--ranks 2] [--repeat 3]
                              [--check-energy] [--splits box metis ...] [--turns 1]
                              [--out cube_obstacle_peer.json]
Writes bench/results/OUT and prints a markdown table."""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

from common import CUBE_OBSTACLE_TOML, env, petsc_program, save, solve

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--n", type=int, nargs="+", default=[40, 80])
p.add_argument("--amplitude", type=float, nargs="+", default=[1.0, 20.0])
p.add_argument("--ranks", type=int, default=2)
p.add_argument("--repeat", type=int, default=3)
p.add_argument("--rtol", type=float, default=1e-4)
p.add_argument("--check-energy", action="store_true")
p.add_argument("--turns", type=int, default=1,
               help="run the peer and the htfeti rows this many times in turns (odd turns: the "
                    "peer, then each split; even turns: the splits, then the peer); wall times "
                    "and ratios are the medians over the turns, so that a drift of the machine "
                    "and the order fall on every code alike")
p.add_argument("--splits", nargs="+", default=["box", "metis", "box_preconditioned",
                                               "metis_preconditioned"],
               help="the htfeti rows to run (default: these four; also box_projected_cg, "
                    "metis_projected_cg, box_gradient, metis_gradient, box_dirichlet, "
                    "metis_dirichlet, box_double, metis_double, metis_dirichlet_double, "
                    "metis_shape)")
p.add_argument("--out", default="cube_obstacle_peer.json")
a = p.parse_args()

exe = petsc_program("petsc_cube_obstacle")



def peer(n, amp, rtol):
    cmd = ["mpiexec", "-n", str(a.ranks), "--oversubscribe", "--bind-to", "none", exe,
           "-n", str(n), "-amp", repr(amp), "-rtol", repr(rtol)]
    t0 = time.perf_counter()
    out = subprocess.run(cmd, check=True, env=env(1), capture_output=True, text=True).stdout
    r = json.loads(out.strip().splitlines()[-1])
    r["wall_s"] = time.perf_counter() - t0
    if not r["converged"]:
        sys.exit(f"the peer did not converge: {r}")
    return r


def repeated(run):
    runs = [run()]
    while len(runs) < a.repeat and runs[-1]["wall_s"] < 60:
        runs.append(run())
    return runs


def htfeti(path, extra=()):
    r = solve([path, *extra], threads=a.ranks)
    r["wall_s"] = r["wall_seconds"]
    if not r["converged"]:
        sys.exit(f"htfeti did not converge on {path}")
    return r


def peer_row(n, amp, err):
    """The peer's runs of one turn (repeated as --repeat says)."""
    runs = repeated(lambda: peer(n, amp, a.rtol))
    r = runs[0]
    return {"code": f"PETSc SNES VI (rsls) + CG/GAMG, {a.ranks} ranks",
            "runs": len(runs), "wall_s": statistics.median(x["wall_s"] for x in runs),
            "total_s": statistics.median(x["total_s"] for x in runs),
            "newton_iterations": r["newton_iterations"], "cg_iterations": r["cg_iterations"],
            "peak_rss_gb": r["peak_rss_mb_sum"] / 1024, "energy": r["objective"],
            "energy_error": err(r["objective"]), "contact_nodes": r["contact_nodes"]}


def one_turn(n, amp, ns, tmp, ref, err, check, peer_first=True):
    """The peer and every split once (each repeated as --repeat says): one turn's row. The peer
    runs first, or after the splits when peer_first is false (row["order"] says which)."""
    row = {"n": n, "amplitude": amp, "reference_energy": ref,
           "order": "peer first" if peer_first else "peer last"}
    if peer_first:
        row["peer"] = peer_row(n, amp, err)
    pre = ["--mprgp-expansion", "preconditioned"]
    pcg = ["--mprgp-expansion", "projected-cg"]
    grd = ["--mprgp-expansion", "gradient"]
    dir_ = ["--preconditioner", "dirichlet"]
    dbl = ["--factor-precision", "double"]
    for split, sub, extra in (("box", f"[{ns}, {ns}, {ns}]", []),
                              ("box_double", f"[{ns}, {ns}, {ns}]", dbl),
                              ("metis_double", str(ns ** 3), dbl),
                              ("metis_dirichlet_double", str(ns ** 3), dir_ + dbl),
                              ("metis", str(ns ** 3), []),
                              ("metis_shape", str(ns ** 3), ["--partition-shape", "metis"]),
                              ("box_preconditioned", f"[{ns}, {ns}, {ns}]", pre),
                              ("metis_preconditioned", str(ns ** 3), pre),
                              ("box_projected_cg", f"[{ns}, {ns}, {ns}]", pcg),
                              ("metis_projected_cg", str(ns ** 3), pcg),
                              ("box_gradient", f"[{ns}, {ns}, {ns}]", grd),
                              ("metis_gradient", str(ns ** 3), grd),
                              ("box_dirichlet", f"[{ns}, {ns}, {ns}]", dir_),
                              ("metis_dirichlet", str(ns ** 3), dir_)):
        if split not in a.splits:
            continue
        path = os.path.join(tmp, f"c{n}_{split}_{amp}.toml")
        with open(path, "w") as f:
            f.write(CUBE_OBSTACLE_TOML.format(n=n, amp=amp, subdomains=sub, rtol=a.rtol))
        hr = repeated(lambda: htfeti(path, extra))
        h = hr[0]
        what = split.replace("_preconditioned", " split, preconditioned expansion")
        what = what.replace("_projected_cg", " split, projected CG expansion")
        what = what.replace("_gradient", " split, gradient expansion")
        what = what.replace("_dirichlet", " split, Dirichlet preconditioner")
        what = what.replace("_double", " split, double-precision factor sweeps")
        what = what.replace("_shape", " split, METIS's own parts")
        what = what.replace("split split", "split")
        what = what if "split" in what else what + " split"
        row[split] = {"code": f"htfeti TFETI, {what}, 1 rank x {a.ranks} threads",
                      "runs": len(hr), "wall_s": statistics.median(x["wall_s"] for x in hr),
                      "total_s": statistics.median(x["timings"]["total"] for x in hr),
                      "products": h["matvecs"], "outer_iterations": h["outer_iterations"],
                      "expansion_steps": h["solver"].get("expansion_steps"),
                      "expansion_cost_increases":
                          h["solver"].get("expansion_cost_increases"),
                      "preconditioner": h.get("preconditioner"),
                      "factor_precision": h.get("factor_precision"),
                      "single_check_products":
                          h["solver"].get("single_sweeps", {}).get("check_products"),
                      "peak_rss_gb": h["memory"]["peak_rss_mb_max_rank"] / 1024,
                      "energy": h["objective"], "energy_error": err(h["objective"])}
        if a.check_energy:
            with open(path, "w") as f:
                f.write(CUBE_OBSTACLE_TOML.format(n=n, amp=amp, subdomains=sub, rtol=1e-8))
            tight = htfeti(path, extra)["objective"]
            row[split]["tight_energy_error"] = err(tight)
            if err(tight) > 1e-8:
                sys.exit(f"n={n} A={amp} {split}: htfeti's energy at rtol 1e-8 "
                         f"{tight!r} differs from the peer's {ref!r} by {err(tight):.2e}")
    if not peer_first:
        row["peer"] = peer_row(n, amp, err)
    for split in a.splits:
        row[f"ratio_{split}_to_peer"] = row[split]["wall_s"] / row["peer"]["wall_s"]
    for split in ("metis", "metis_preconditioned", "metis_projected_cg", "metis_gradient",
                  "metis_dirichlet", "metis_double", "metis_dirichlet_double", "metis_shape"):
        if split in row and "box" in row:
            row[f"products_{split}_to_box"] = (row[split]["products"] /
                                               row["box"]["products"])
    return row


rows = []
with tempfile.TemporaryDirectory() as tmp:
    for n in a.n:
        ns = n // 10
        for amp in a.amplitude:
            ref = peer(n, amp, 1e-10)["objective"]
            err = lambda e: abs(e - ref) / abs(ref)  # noqa: E731
            # The order alternates: whichever code runs second meets the pages the first
            # one freed (the peer at 80^3 frees about 12 GB, htfeti about 5).
            turns = [one_turn(n, amp, ns, tmp, ref, err, a.check_energy and t == 0,
                              peer_first=t % 2 == 0)
                     for t in range(a.turns)]
            row = turns[0]
            if a.turns > 1:  # medians over the turns; each turn's ratios kept
                for code in ["peer", *a.splits]:
                    walls = [t[code]["wall_s"] for t in turns]
                    row[code]["walls_by_turn"] = walls
                    row[code]["wall_s"] = statistics.median(walls)
                row["order_by_turn"] = [t["order"] for t in turns]
                for split in a.splits:
                    ratios = [t[split]["wall_s"] / t["peer"]["wall_s"] for t in turns]
                    row[f"ratios_{split}_to_peer_by_turn"] = ratios
                    row[f"ratio_{split}_to_peer"] = statistics.median(ratios)
            row["turns"] = a.turns
            rows.append(row)
            print(json.dumps(row), flush=True)

print(f"\ncube-obstacle, {a.ranks} cores (PETSc: {a.ranks} ranks; htfeti: 1 rank x {a.ranks} "
      f"threads), rtol {a.rtol}\n")
print("| n | A | code | iterations | wall s | peak RSS GB | energy error | wall / peer |")
print("|---:|---:|---|---|---:|---:|---:|---:|")
for r in rows:
    pe = r["peer"]
    print(f"| {r['n']} | {r['amplitude']:g} | {pe['code']} | {pe['newton_iterations']} Newton, "
          f"{pe['cg_iterations']} CG | {pe['wall_s']:.1f} | {pe['peak_rss_gb']:.2f} | "
          f"{pe['energy_error']:.1e} | 1 |")
    for split in a.splits:
        h = r[split]
        print(f"| {r['n']} | {r['amplitude']:g} | {h['code']} | {h['products']} products | "
              f"{h['wall_s']:.1f} | {h['peak_rss_gb']:.2f} | {h['energy_error']:.1e} | "
              f"{r[f'ratio_{split}_to_peer']:.2f} |")
print("\nwritten:", save(a.out, {"ranks": a.ranks, "rtol": a.rtol, "repeat": a.repeat,
                                 "rows": rows}))
