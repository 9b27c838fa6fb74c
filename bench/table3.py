#!/usr/bin/env python3
"""The paper's Table 3 in its shape: the semicoercive membranes variational inequality with
N_s = 32 subdomains per membrane side (2 x 1024 subdomains), clusters of m x m subdomains joined
by edge averages, m = 1, 2, 4, 8 (m = 1 is TFETI), SMALBE-M + MPRGP at eps = 1e-4.

Default: a reduced H_s/h (16) that runs in a minute here. --full runs the paper's size
(n = 3168, H_s/h = 99, 20,480,000 primal unknowns, 3,169 inequalities): opt-in, it needs about
10 GB and several minutes per m.

Usage: bench/table3.py [--hh 16 | --full] [--ms 1 2 4 8] [--ranks 1] [--threads 2]
       [--extra "more htfeti solve arguments"] [--vtu] [--out table3_custom.json]
--vtu writes the VTU output too; the "wall s" column is the whole process, output included.
Writes bench/results/table3_hh<H>.json and prints the table next to the paper's numbers."""
import argparse

from common import save, solve

PAPER = {1: (52, 243, 2048), 2: (25, 252, 512), 4: (16, 186, 128), 8: (12, 218, 32)}

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--hh", type=int, default=16, help="H_s/h (elements per subdomain side)")
p.add_argument("--full", action="store_true", help="the paper's size, H_s/h = 99 (n = 3168)")
p.add_argument("--ms", type=int, nargs="+", default=[1, 2, 4, 8])
p.add_argument("--ns", type=int, default=32, help="subdomains per membrane side")
p.add_argument("--glue", default="averages")
p.add_argument("--ranks", type=int, default=1)
p.add_argument("--threads", type=int, default=2)
p.add_argument("--extra", default="", help="further htfeti solve arguments, quoted")
p.add_argument("--out", default=None,
               help="the JSON file in bench/results (default table3_hh<H_s/h>.json)")
p.add_argument("--vtu", action="store_true", help="write the VTU output too (timed)")
a = p.parse_args()
hh = 99 if a.full else a.hh
n = a.ns * hh

runs = []
print(f"membranes, n = {n}, N_s = {a.ns}, H_s/h = {hh}, glue = {a.glue}, "
      f"{a.ranks} ranks x {a.threads} threads")
print("| m | outer iter | matrix x vector | coarse dim | paper: outer / matvecs / coarse | "
      "primal | inequalities | energy | solve s | total s | wall s |")
print("|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|")
for m in a.ms:
    r = solve(["--problem", "membranes", "-n", n, "--subdomains", a.ns, "-m", m, "--glue", a.glue,
               *a.extra.split()], ranks=a.ranks, threads=a.threads, vtu=a.vtu)
    runs.append(r)
    save(a.out or f"table3_hh{hh}.json", {"command": "(partial)", "paper": PAPER, "runs": runs})
    pp = PAPER.get(m, ("-", "-", "-"))
    print(f"| {m} | {r['outer_iterations']} | {r['matvecs']} | {r['coarse_dimension']} | "
          f"{pp[0]} / {pp[1]} / {pp[2]} | {r['primal_dimension']} | {r['inequalities']} | "
          f"{r['objective']:.10f} | {r['timings']['solve']:.1f} | {r['timings']['total']:.1f} | "
          f"{r['wall_seconds']:.1f} |",
          flush=True)
cmd = "bench/table3.py " + ("--full" if a.full else f"--hh {hh}") + \
      f" --ms {' '.join(map(str, a.ms))} --ranks {a.ranks} --threads {a.threads}" + \
      (f' --extra "{a.extra}"' if a.extra else "") + (" --vtu" if a.vtu else "") + \
      (f" --out {a.out}" if a.out else "")
print("\n" + save(a.out or f"table3_hh{hh}.json", {"command": cmd, "paper": PAPER, "runs": runs}))
