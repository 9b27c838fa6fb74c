#!/usr/bin/env python3
"""Iterations and wall time with the FETI preconditioners none / lumped / Dirichlet.

Sections (--sections, default all but the slow ones):
  poisson   poisson2d (linear, PCG), 8 x 8 subdomains, H_s/h = 16, 32, 64, 100, TFETI (m = 1)
            and H-TFETI-DP (m = 4), eps = 1e-4 (Table 2's shape at small size);
  membranes the Table 3 membranes (contact, SMALBE-M + MPRGP in face), N_s = 32, H_s/h = 16,
            m = 1, 2, 4, 8 (Table 3 reduced); `--membranes-full` adds m = 8 at the paper's size;
  cube      the cube-obstacle (3D elastic contact, Table 4's ladder): k x k x k clusters of 4^3
            subdomains of 10^3 hex8, TFETI and H-TFETI-DP, k = 1 (--cube-k 1 2 adds the 2 x 2 x 2
            row: about 7 GB and several minutes per run);
  clusters  H-TFETI-DP with contact on smaller clusters (the automatic choice for elasticity):
            the cube-obstacle 40^3, 4^3 subdomains in clusters of 2^3 (box split), and the
            same cube split by METIS into 64 parts in clusters of 8 (bench/cases,
            cube40_metis64.toml --cluster-size 8);
  hetero    coefficient jumps between subdomains (1e3 and 1e6): Laplace on the unit square,
            8 x 8 subdomains, H_s/h = 16, the coefficient jumping across x = 0.5 (stripes) and in
            a checkerboard; plane-strain elasticity on the plate-with-hole Gmsh part (METIS, 16
            subdomains) whose right half (x > 1) is stiffer;
            none / lumped / Dirichlet x multiplicity / stiffness scaling, eps = 1e-8.
Wall times are medians of --repeat runs (3 by default; 1 for the cube).

Usage: bench/preconditioners.py [--sections poisson membranes cube clusters hetero] [--threads 2]
       [--precs none lumped dirichlet] [--cube-k 1 2] [--cube-key cube]
       [--membranes-hh 16 99] [--membranes-key membranes] [--dirichlet-storage dense]
Writes bench/results/preconditioners.json (sections merged into the existing file) and prints
markdown tables."""
import argparse
import json
import os
import statistics
import tempfile

from common import JUMP_PLATE_TOML, JUMP_SQUARE_TOML, RESULTS, ROOT, save, solve

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--sections", nargs="+",
               default=["poisson", "membranes", "hetero", "cube", "clusters"])
p.add_argument("--threads", type=int, default=2)
p.add_argument("--repeat", type=int, default=3)
p.add_argument("--cube-k", type=int, nargs="+", default=[1])
p.add_argument("--membranes-full", action="store_true",
               help="add m = 8 at the paper's size (n = 3168, H_s/h = 99)")
p.add_argument("--membranes-hh", type=int, nargs="+", default=[16],
               help="16: Table 3 reduced (m = 1, 2, 4, 8); 99: m = 8 at the paper's size")
p.add_argument("--membranes-key", default="membranes",
               help="the JSON key of the membranes section")
p.add_argument("--dirichlet-storage", default=None,
               help="passed on as --dirichlet-storage with the Dirichlet runs")
p.add_argument("--precs", nargs="+", default=["none", "lumped", "dirichlet"],
               help="the preconditioners to run")
p.add_argument("--cube-key", default="cube", help="the JSON key of the cube section")
a = p.parse_args()

PRECS = a.precs


def storage(pc):
    return (["--dirichlet-storage", a.dirichlet_storage]
            if a.dirichlet_storage and pc == "dirichlet" else [])


def run(args, repeat):
    reps = [solve(args, threads=a.threads) for _ in range(repeat)]
    r = reps[0]
    t = r["timings"]
    return {
        "args": " ".join(map(str, args)),
        "preconditioner": r["preconditioner"],
        "scaling": r["scaling"],
        "storage": r.get("preconditioner_storage", ""),
        "converged": r["converged"],
        "outer": r["outer_iterations"],
        "inner": r["inner_iterations"],
        "matvecs": r["matvecs"],
        "preconditioner_applications": r["preconditioner_applications"],
        "objective": r["objective"],
        "primal": r["primal_dimension"],
        "total_s": statistics.median(x["timings"]["total"] for x in reps),
        "solve_s": statistics.median(x["timings"]["solve"] for x in reps),
        "preconditioner_setup_s": statistics.median(
            x["timings"]["preconditioner_setup"] for x in reps),
        "preconditioner_mb": r["memory"]["preconditioner_mb"],
        "repeat": repeat,
    }


def table(title, rows, key_cols):
    print(f"\n{title}\n")
    hdr = key_cols + ["prec.", "outer", "inner", "F products", "M^-1", "solve s", "total s",
                      "M setup s", "energy"]
    print("| " + " | ".join(hdr) + " |")
    print("|" + "---|" * len(hdr))
    for k, r in rows:
        print("| " + " | ".join(map(str, k)) +
              f" | {r['preconditioner']} | {r['outer']} | {r['inner']} | {r['matvecs']} | "
              f"{r['preconditioner_applications']} | {r['solve_s']:.2f} | {r['total_s']:.2f} | "
              f"{r['preconditioner_setup_s']:.2f} | {r['objective']:.10e} |"
              + ("" if r["converged"] else " (not converged)"))


out = {}
path = os.path.join(RESULTS, "preconditioners.json")
if os.path.exists(path):
    with open(path) as f:
        out = json.load(f)
    out.pop("machine", None)

if "poisson" in a.sections:
    rows = []
    for m in [1, 4]:
        for hh in [16, 32, 64, 100]:
            for pc in PRECS:
                r = run(["--problem", "poisson2d", "-n", 8 * hh, "--subdomains", 8, "-m", m,
                         "--preconditioner", pc], a.repeat)
                rows.append(((m, hh), r))
    table("poisson2d, 8 x 8 subdomains, eps = 1e-4 (m = 1: TFETI)", rows, ["m", "H_s/h"])
    out["poisson"] = [dict(r, m=k[0], hh=k[1]) for k, r in rows]
    save("preconditioners.json", out)

if "membranes" in a.sections:
    rows = []
    hhs = a.membranes_hh + ([99] if a.membranes_full and 99 not in a.membranes_hh else [])
    cases = [(m, hh) for hh in hhs for m in ([1, 2, 4, 8] if hh == 16 else [8])]
    for m, hh in cases:
        for pc in PRECS:
            r = run(["--problem", "membranes", "-n", 32 * hh, "--subdomains", 32, "-m", m,
                     "--preconditioner", pc] + storage(pc), a.repeat if hh == 16 else 1)
            rows.append(((m, hh), r))
    table("membranes (Table 3), N_s = 32, eps = 1e-4", rows, ["m", "H_s/h"])
    out[a.membranes_key] = [dict(r, m=k[0], hh=k[1]) for k, r in rows]
    save("preconditioners.json", out)

if "hetero" in a.sections:
    rows = []
    square, plate = JUMP_SQUARE_TOML.replace("{n}", "128"), JUMP_PLATE_TOML
    with tempfile.TemporaryDirectory() as d:
        for jump in [1e3, 1e6]:
            for name, tmpl, coef, m in [
                ("square stripes", square, f"x > 0.5 ? {jump:g} : 1", 1),
                ("square checkerboard", square,
                 f"sin(8*pi*x)*sin(8*pi*y) > 0 ? {jump:g} : 1", 1),
                ("plate-with-hole", plate, f"x > 1 ? {jump:g} : 1", 1),
            ]:
                f = os.path.join(d, "h.toml")
                with open(f, "w") as fh:
                    fh.write(tmpl.format(coef=coef, m=m, mesh=os.path.join(
                        ROOT, "examples", "meshes", "plate-with-hole.msh")))
                for pc in PRECS:
                    for sc in (["multiplicity"] if pc == "none" else
                               ["multiplicity", "stiffness"]):
                        r = run([f, "--preconditioner", pc, "--scaling", sc], a.repeat)
                        rows.append(((name, f"{jump:g}", sc), r))
    table("coefficient jumps, eps = 1e-8 (TFETI)", rows, ["problem", "jump", "scaling"])
    out["hetero"] = [dict(r, problem=k[0], jump=k[1]) for k, r in rows]
    save("preconditioners.json", out)

if "cube" in a.sections:
    rows = []
    for k in a.cube_k:
        for m, name in [(1, "TFETI"), (4, "H-TFETI-DP")]:
            for pc in PRECS:
                r = run(["--problem", "cube-obstacle", "--elements", ",".join([str(40 * k)] * 3),
                         "--subdomains", ",".join([str(4 * k)] * 3), "-m", m,
                         "--preconditioner", pc] + storage(pc), 1)
                rows.append(((f"{k}x{k}x{k}", name), r))
                out[a.cube_key] = [dict(r, clusters=k[0], method=k[1]) for k, r in rows]
                save("preconditioners.json", out)  # a row at a time: these runs are long
    table("cube-obstacle (Table 4), eps = 1e-4", rows, ["clusters", "method"])
    out[a.cube_key] = [dict(r, clusters=k[0], method=k[1]) for k, r in rows]

if "clusters" in a.sections:
    rows = []
    metis = os.path.join(ROOT, "bench", "cases", "cube40_metis64.toml")
    for name, args in [
        ("box 40^3, 4^3 subdomains, clusters of 2^3",
         ["--problem", "cube-obstacle", "--elements", "40,40,40", "--subdomains", "4,4,4",
          "-m", 2]),
        ("METIS 40^3, 64 parts, clusters of 8", [metis, "--cluster-size", 8]),
    ]:
        for pc in PRECS:
            r = run(args + ["--preconditioner", pc] + storage(pc), a.repeat)
            rows.append(((name,), r))
    table("H-TFETI-DP with contact, smaller clusters, eps = 1e-4", rows, ["case"])
    out["clusters"] = [dict(r, case=k[0]) for k, r in rows]

print("\nwritten:", save("preconditioners.json", out))
