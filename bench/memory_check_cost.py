#!/usr/bin/env python3
"""What refusing a problem that cannot fit in memory costs: wall seconds and peak resident memory
of `htfeti solve` ending with exit 2 under a small --memory-limit, for one large subdomain of a
generated box and for a generated box split by METIS (no two subdomains equal). With --before,
an older build runs the same cases, interleaved; medians of --repeat runs.

Usage: bench/memory_check_cost.py [--before /tmp/htfeti-before] [--after build/htfeti]
                                   [--repeat 3] [--out memory_check_cost.json]"""
import argparse
import os
import statistics
import subprocess
import tempfile
import time

from common import ROOT, env, save

BOX80_METIS = """[mesh]
generator = "box"
size = [100.0, 100.0, 100.0]
elements = [80, 80, 80]
element = "hex8"
[physics]
type = "elasticity"
young = 2.1e7
poisson = 0.3
[[dirichlet]]
group = "x0"
value = [0.0, 0.0, 0.0]
[decomposition]
subdomains = 64
"""

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--before", default=None)
p.add_argument("--after", default=os.path.join(ROOT, "build", "htfeti"))
p.add_argument("--repeat", type=int, default=3)
p.add_argument("--out", default="memory_check_cost.json")
a = p.parse_args()

work = tempfile.mkdtemp(prefix="htfeti-memcheck-")
with open(os.path.join(work, "box80.toml"), "w") as f:
    f.write(BOX80_METIS)
CASES = {
    "one 40^3 subdomain (box), --memory-limit 0.01":
        ["--problem", "cube-obstacle", "--elements", "40,40,40", "--subdomains", "1,1,1",
         "--memory-limit", "0.01"],
    "80^3 box split by METIS into 64, --memory-limit 0.05":
        [os.path.join(work, "box80.toml"), "--memory-limit", "0.05"],
}


def run_isolated(binary, args):
    # A fresh Python child per measurement so that ru_maxrss is this run's alone.
    code = ("import resource,subprocess,sys,time\n"
            "t=time.perf_counter();r=subprocess.run(sys.argv[1:],capture_output=True)\n"
            "w=time.perf_counter()-t\n"
            "print(r.returncode,w,resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss/1024)")
    out = subprocess.run(["python3", "-c", code, binary, "solve", *args, "--no-report",
                          "--no-vtu"], cwd=work, env=env(2), capture_output=True, text=True)
    if not out.stdout.strip():
        raise SystemExit(f"{binary} {args}: no measurement\n{out.stderr}")
    code_, wall, mb = out.stdout.split()
    if int(code_) != 2:
        raise SystemExit(f"{binary} {args}: exit {code_}, expected 2\n{out.stderr}")
    return float(wall), float(mb)


builds = [("after", os.path.abspath(a.after))] + (
    [("before", os.path.abspath(a.before))] if a.before else [])
rows = []
print("| case | build | wall s (median) | peak MB (median) |")
print("|---|---|---:|---:|")
for name, args in CASES.items():
    samples = {label: [] for label, _ in builds}
    for _ in range(a.repeat):
        for label, binary in builds:  # interleaved
            samples[label].append(run_isolated(binary, args))
    for label, _ in builds:
        wall = statistics.median(s[0] for s in samples[label])
        mb = statistics.median(s[1] for s in samples[label])
        rows.append({"case": name, "build": label, "wall_s": wall, "peak_mb": mb,
                     "samples": samples[label]})
        print(f"| {name} | {label} | {wall:.2f} | {mb:.0f} |", flush=True)
print(save(a.out, {"command": "bench/memory_check_cost.py" +
                   (" --before BEFORE" if a.before else ""), "repeat": a.repeat, "rows": rows}))
