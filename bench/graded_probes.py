#!/usr/bin/env python3
"""The strongly graded Hertz block's measurements that need a probe build, made rerunnable:
bench/probes/graded_probes.patch adds environment-variable probes (not part of htfeti) to a
copy of the sources, and this script builds that copy and runs them.

Probes (the block under a uniform traction, PCG, 16 METIS parts, rtol 1e-4, unless named):
- HTFETI_PROBE_EIG=300: power iteration on P M^-1 P F; the top eigenvector's weight per kind of
  row (gluing, Dirichlet) and its largest rows with their nodes' coordinates;
- HTFETI_PROBE_IBOX=a,b,c: the mesh split in index space (a x b x c boxes of cell layers);
  HTFETI_PROBE_WEIGHT=p: METIS's facet weights area / distance^p; HTFETI_PROBE_UFACTOR=u:
  METIS's imbalance 1 + u/1000;
- HTFETI_PROBE_PRIMAL_DIRICHLET=1: Dirichlet dofs decoupled in K_i instead of Dirichlet rows,
  kernels restricted to the rigid motions they allow (FETI-1's treatment), linear and contact;
- HTFETI_PROBE_DEFLATE=k,s: subspace iteration with k vectors and s sweeps on P M^-1 P F (the
  Ritz values of the subspace), then PCG deflated by the top m Ritz vectors, m = 0 ... 20;
- for comparison, options of htfeti itself: the weighted projector, and the contact run with the
  Dirichlet preconditioner and with one layer of it (MPRGP's CG steps and the face iterations).
The largest eigenvalue and the counts are read from the report (solver.spectrum_estimate,
matvecs); counts do not depend on the machine's speed.

Usage: bench/graded_probes.py [--threads 2] [--out graded_probes.json]
Writes bench/results/OUT. Builds in a temporary directory (some minutes on 2 cores)."""
import argparse
import collections
import os
import re
import subprocess
import tempfile

from common import ROOT, machine, save, solve
from hertz_cases import contact_problems

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--threads", type=int, default=2)
p.add_argument("--out", default="graded_probes.json")
a = p.parse_args()

LINEAR = '[[load]]\ngroup = "top"\ntraction = [0.0, 0.0, -1.0]\n'


def linear_file(toml, path):
    with open(toml) as f:
        t = f.read()
    with open(path, "w") as f:
        f.write(t[:t.index("[[contact]]")] + LINEAR)
    return path


def build(tmp):
    src = os.path.join(tmp, "src")
    subprocess.run(["git", "-C", ROOT, "worktree", "add", "--detach", src, "HEAD"], check=True,
                   stdout=subprocess.DEVNULL)
    subprocess.run(["git", "-C", src, "apply",
                    os.path.join(ROOT, "bench", "probes", "graded_probes.patch")], check=True)
    b = os.path.join(tmp, "build")
    subprocess.run([os.path.join(src, "scripts", "configure.sh"), b,
                    "-DCMAKE_BUILD_TYPE=Release"], check=True, stdout=subprocess.DEVNULL)
    subprocess.run(["cmake", "--build", b, "-j", str(os.cpu_count()), "--target", "htfeti"],
                   check=True, stdout=subprocess.DEVNULL)
    return src, os.path.join(b, "htfeti")


def stderr_of(binary, args, env, cwd):
    e = dict(os.environ, OMP_NUM_THREADS=str(a.threads), **env)
    done = subprocess.run([binary, "solve", *map(str, args), "--no-vtu", "--report", "r.json"],
                          env=e, cwd=cwd, capture_output=True, text=True, check=True)
    return done.stderr


rows = []
with tempfile.TemporaryDirectory() as tmp:
    src, binary = build(tmp)
    try:
        hertz = contact_problems(tmp)
        strong, uniform = hertz[0][1], hertz[2][1]
        lin, lin_uniform = linear_file(strong, f"{tmp}/lin.toml"), linear_file(uniform,
                                                                                f"{tmp}/linu.toml")

        def run(case, args, env):
            r = solve(args, threads=a.threads, binary=binary, extra_env=env)
            e = r["solver"].get("spectrum_estimate") or r["solver"].get("face_spectrum_estimate")
            row = {"case": case, "args": [str(x) for x in args[1:]], "env": env,
                   "products": r["matvecs"], "largest": e["max"] if e else None,
                   "coarse_dimension": r["coarse_dimension"], "energy": r["objective"],
                   "mprgp_cg_steps": r["solver"].get("cg_steps"),
                   "face_iterations": r["solver"].get("face_iterations")}
            rows.append(row)
            print(f"{case:28s} {' '.join(row['args']):28s} {env} {row['products']} products, "
                  f"largest {row['largest']:.4g}, coarse {row['coarse_dimension']}", flush=True)

        # Where the top eigenvector lives.
        for pre in ("lumped", "dirichlet"):
            err = stderr_of(binary, [lin, "--preconditioner", pre], {"HTFETI_PROBE_EIG": "300"},
                            tmp)
            head = re.search(r"PROBE_EIG theta (\S+) gluing (\S+) dirichlet (\S+)", err)
            entries = collections.defaultdict(list)
            with open(f"{tmp}/probe_eigvec.txt") as f:
                for line in f:
                    k, s, dof, kind, v = line.split()
                    entries[int(k)].append((int(s), int(dof), int(kind), float(v)))
            coords = {}

            def xyz(s, node):
                if s not in coords:
                    with open(f"{tmp}/probe_coords_{s}.txt") as f:
                        coords[s] = {int(l.split()[0]): [float(x) for x in l.split()[2:]]
                                     for l in f}
                return coords[s][node]
            top = sorted(entries.items(), key=lambda kv: -abs(kv[1][0][3]))[:12]
            rows.append({"case": "top eigenvector", "preconditioner": pre,
                         "eigenvalue": float(head.group(1)),
                         "share_gluing": float(head.group(2)),
                         "share_dirichlet": float(head.group(3)),
                         "rows": [{"kind": ["gluing", "dirichlet", "contact"][e[0][2]],
                                   "component": e[0][1] % 3, "subdomains": [x[0] for x in e],
                                   "xyz": xyz(e[0][0], e[0][1] // 3), "value": e[0][3]}
                                  for _, e in top]})
            print(f"top eigenvector, {pre}: {head.group(0)}", flush=True)
            for r in rows[-1]["rows"]:
                print(f"  {r['kind']:9s} comp {r['component']} parts {r['subdomains']} "
                      f"at {r['xyz']}: {r['value']:.3f}", flush=True)
        # Partitions.
        for boxes in ("2,2,4", "4,2,2", "4,4,1", "1,4,4"):
            for pre in ("lumped", "dirichlet"):
                run("index boxes " + boxes, [lin, "--preconditioner", pre],
                    {"HTFETI_PROBE_IBOX": boxes})
        for w in ("1", "2"):
            run("facet weight area/d^" + w, [lin], {"HTFETI_PROBE_WEIGHT": w})
        for u in ("100", "300", "1000"):
            run("METIS ufactor " + u, [lin], {"HTFETI_PROBE_UFACTOR": u})
        # Options of htfeti itself, for comparison: the weighted projector, and the contact
        # run's products by kind with Dirichlet and one layer of it.
        for pre in ("lumped", "dirichlet"):
            run("weighted projector", [lin, "--preconditioner", pre, "--scaling", "stiffness",
                                       "--pcg-projector", "weighted"], {})
        run("contact", [strong, "--preconditioner", "dirichlet"], {})
        run("contact", [strong, "--preconditioner", "dirichlet", "--dirichlet-layers", 1], {})
        # Primal Dirichlet conditions.
        for f, label in ((lin, "strong"), (lin_uniform, "uniform"), (strong, "strong contact")):
            for pre in ("lumped", "dirichlet"):
                run("TFETI " + label, [f, "--preconditioner", pre], {})
                run("primal Dirichlet " + label, [f, "--preconditioner", pre],
                    {"HTFETI_PROBE_PRIMAL_DIRICHLET": "1"})
        # How many eigenvalues are large, and what deflating them gives.
        for pre, k in (("dirichlet", "24,30"), ("lumped", "84,30")):
            err = stderr_of(binary, [lin, "--preconditioner", pre],
                            {"HTFETI_PROBE_DEFLATE": k}, tmp)
            ritz = [float(x) for x in re.search(r"PROBE_RITZ (.*)", err).group(1).split()]
            deflated = [{"m": int(m), "largest_left": float(l), "iterations": int(i)}
                        for m, l, i in re.findall(
                            r"PROBE_DEFLATE m=(\d+) largest_left (\S+) iterations (\d+)", err)]
            rows.append({"case": "subspace and deflation", "preconditioner": pre,
                         "vectors_sweeps": k, "ritz": ritz, "deflated": deflated})
            print(f"{pre}: Ritz {' '.join(f'{x:.4g}' for x in ritz)}", flush=True)
            print(f"  above 100: {sum(x > 100 for x in ritz)}, above 25: "
                  f"{sum(x > 25 for x in ritz)}", flush=True)
            for d in deflated:
                print(f"  deflated m = {d['m']:2d}: {d['iterations']} iterations (largest left "
                      f"{d['largest_left']:.4g})", flush=True)
    finally:
        subprocess.run(["git", "-C", ROOT, "worktree", "remove", "--force", src])
save(a.out, {"threads": a.threads, "rows": rows, "machine": machine()})
