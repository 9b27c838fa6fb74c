#!/usr/bin/env python3
"""The Dirichlet preconditioner's storage: dense S_i against the implicit S_i (a factor of K_ii),
and what `--dirichlet-storage auto` picks, on the problems where the Dirichlet preconditioner
is chosen (a coefficient field: `--preconditioner auto` takes it) or asked for (elastic contact
on METIS parts and on the graded Hertz block), in 2D and 3D.

Cases (--cases, default all):
  square16, square64, square128  Laplace on the unit square, conductivity 1e4 on x > 0.5, 8 x 8
                      subdomains of H_s/h = 16, 64, 128 quad4 cells (examples/heterogeneous.toml
                      at three sizes), rtol 1e-8;
  plate               plane-strain elasticity on the plate-with-hole Gmsh part, the right half
                      (x > 1) 1e3 times stiffer, 16 METIS parts, rtol 1e-8;
  cube3d              3D elasticity, 24^3 hex8 in 4^3 box subdomains clamped at x = 0 under its
                      own weight, the half x > 50 1e3 times stiffer, rtol 1e-8;
  metis40             the cube-obstacle 40^3 in 64 METIS parts, A = 1
                      (bench/cases/cube40_metis64.toml), `--preconditioner dirichlet`;
  hertz               the strongly graded Hertz block (bench/hertz_cases.py, 16 METIS parts),
                      `--preconditioner dirichlet`.
Each case runs with the storage auto, dense and implicit (the automatic preconditioner and
scaling otherwise). Per run: the storage in effect, Hessian products, the preconditioner's setup
(thread-seconds, within the factorization phase) and application (seconds), its memory, the
factorization and solve phases, the report's total, peak RSS and the energy. Times are medians of
--repeat runs (1 by default; counts need one run).

Usage: bench/dirichlet_storage.py [--cases ...] [--repeat 1] [--threads 2]
                                  [--out dirichlet_storage.json]"""
import argparse
import os
import statistics
import tempfile

from common import JUMP_CUBE_TOML, JUMP_PLATE_TOML, JUMP_SQUARE_TOML, ROOT, save, solve
import hertz_cases

CASES = ["square16", "square64", "square128", "plate", "cube3d", "metis40", "hertz"]
p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--cases", nargs="+", default=CASES, choices=CASES)
p.add_argument("--storages", nargs="+", default=["auto", "dense", "implicit"])
p.add_argument("--repeat", type=int, default=1)
p.add_argument("--threads", type=int, default=2)
p.add_argument("--out", default="dirichlet_storage.json")
a = p.parse_args()

CUBE3D = JUMP_CUBE_TOML.format(field="x > 50 ? 1e3 : 1", split="[4, 4, 4]", rtol="1e-8")


def row_of(r):
    t, mem = r["timings"], r["memory"]
    return {"preconditioner": r.get("preconditioner"),
            "storage": r.get("preconditioner_storage"), "products": r["matvecs"],
            "setup_thread_s": t.get("preconditioner_setup", 0.0),
            "apply_s": t.get("preconditioner", 0.0),
            "preconditioner_mb": mem.get("preconditioner_mb"),
            "factorization_s": t["factorization"], "solve_s": t["solve"], "total_s": t["total"],
            "peak_rss_mb": mem.get("peak_rss_mb_max_rank"), "energy": r["objective"]}


def run(args, repeat):
    runs = [row_of(solve(args, threads=a.threads)) for _ in range(repeat)]
    out = dict(runs[0])
    for k in ["setup_thread_s", "apply_s", "factorization_s", "solve_s", "total_s"]:
        out[k] = statistics.median(x[k] for x in runs)
    out["total_s_runs"] = [x["total_s"] for x in runs]
    return out


rows = []
with tempfile.TemporaryDirectory() as d:
    files = {}
    for n, name in [(128, "square16"), (512, "square64"), (1024, "square128")]:
        files[name] = (os.path.join(d, f"{name}.toml"),
                       JUMP_SQUARE_TOML.format(n=n, coef="x > 0.5 ? 1e4 : 1", m=1), [])
    files["plate"] = (os.path.join(d, "plate.toml"), JUMP_PLATE_TOML.format(
        mesh=os.path.join(ROOT, "examples", "meshes", "plate-with-hole.msh"),
        coef="x > 1 ? 1e3 : 1", m=1), [])
    files["cube3d"] = (os.path.join(d, "cube3d.toml"), CUBE3D, [])
    for name, (path, text, _) in list(files.items()):
        with open(path, "w") as f:
            f.write(text)
    files["metis40"] = (os.path.join(ROOT, "bench", "cases", "cube40_metis64.toml"), None,
                        ["--preconditioner", "dirichlet"])
    if "hertz" in a.cases:
        hz = os.path.join(d, "hz")
        os.makedirs(hz)
        path = hertz_cases.contact_problems(hz)[0][1]
        files["hertz"] = (path, None, ["--preconditioner", "dirichlet"])
    for case in a.cases:
        path, _, extra = files[case]
        for storage in a.storages:
            r = run([path, *extra, "--dirichlet-storage", storage], a.repeat)
            r.update(case=case, asked=storage)
            rows.append(r)
            print(f"{case:10s} {storage:8s} -> {r['storage']}: {r['products']} products, setup "
                  f"{r['setup_thread_s']:.2f} thread-s, M^-1 {r['apply_s']:.2f} s, factorization "
                  f"{r['factorization_s']:.2f} s, solve {r['solve_s']:.2f} s, total "
                  f"{r['total_s']:.2f} s, {r['preconditioner_mb']} MB", flush=True)

save(a.out, {"repeat": a.repeat, "threads": a.threads, "rows": rows})
print("\n| case | asked | storage | products | setup thread-s | M^-1 s | factorization s | "
      "solve s | total s | preconditioner MB |")
print("|---|---|---|---:|---:|---:|---:|---:|---:|---:|")
for r in rows:
    print(f"| {r['case']} | {r['asked']} | {r['storage']} | {r['products']} | "
          f"{r['setup_thread_s']:.2f} | {r['apply_s']:.2f} | {r['factorization_s']:.2f} | "
          f"{r['solve_s']:.2f} | {r['total_s']:.2f} | {r['preconditioner_mb']} |")
