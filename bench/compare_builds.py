#!/usr/bin/env python3
"""Wall time of two htfeti builds on the same cases (medians), e.g. before and after a change.

The "before" binary is built from an older commit, for example:
    git worktree add /tmp/htfeti-before <commit> && cmake -S /tmp/htfeti-before -B /tmp/htfeti-before/b \
        -DCMAKE_BUILD_TYPE=Release && cmake --build /tmp/htfeti-before/b -j2 --target htfeti_app

Usage: bench/compare_builds.py --before /tmp/htfeti-before/b/htfeti [--after build/htfeti]
           [--repeat 3] [--full] [--threads 2]
Cases: membranes n = 1024, N_s = 32, m = 4 with the VTU written (default), and with --full the
Table 3 full size (n = 3168, N_s = 32) for m = 4 (about 10 GB and two minutes per run).
Writes bench/results/compare_builds.json."""
import argparse
import json
import os
import statistics
import subprocess
import tempfile
import time

from common import ROOT, env, save

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--before", required=True)
p.add_argument("--after", default=os.path.join(ROOT, "build", "htfeti"))
p.add_argument("--repeat", type=int, default=3)
p.add_argument("--threads", type=int, default=2)
p.add_argument("--full", action="store_true")
a = p.parse_args()

cases = [("membranes n=1024 N_s=32 m=4, VTU written",
          ["--problem", "membranes", "-n", "1024", "--subdomains", "32", "-m", "4"], True, a.repeat)]
if a.full:
    cases.append(("Table 3 full, m=4 (no VTU)",
                  ["--problem", "membranes", "-n", "3168", "--subdomains", "32", "-m", "4"], False, 1))

rows = []
for name, args, vtu, repeat in cases:
    row = {"case": name, "args": args}
    for label, binary in (("before", a.before), ("after", a.after)):
        walls, reports = [], []
        for _ in range(repeat):
            with tempfile.TemporaryDirectory() as d:
                cmd = [binary, "solve", *args, "--report", os.path.join(d, "r.json")]
                cmd += ["--vtu", os.path.join(d, "u.vtu")] if vtu else ["--no-vtu"]
                t0 = time.perf_counter()
                subprocess.run(cmd, check=True, env=env(a.threads), stdout=subprocess.DEVNULL)
                walls.append(time.perf_counter() - t0)
                with open(os.path.join(d, "r.json")) as f:
                    reports.append(json.load(f))
                vtu_bytes = os.path.getsize(os.path.join(d, "u.vtu")) if vtu else 0
        r = reports[0]
        row[label] = {"wall_median_s": statistics.median(walls), "walls_s": walls,
                      "outer": r["outer_iterations"], "matvecs": r["matvecs"],
                      "energy": r["objective"], "timings": r["timings"],
                      "peak_rss_mb": r["memory"]["peak_rss_mb_max_rank"], "vtu_bytes": vtu_bytes}
    b, f = row["before"], row["after"]
    print(f"{name}: before {b['wall_median_s']:.2f} s, after {f['wall_median_s']:.2f} s "
          f"(outer {b['outer']}/{f['outer']}, matvecs {b['matvecs']}/{f['matvecs']}, "
          f"energy rel. diff {abs(b['energy'] - f['energy']) / abs(b['energy']):.1e}, "
          f"VTU {b['vtu_bytes'] / 1e6:.0f}/{f['vtu_bytes'] / 1e6:.0f} MB)", flush=True)
    rows.append(row)
cmd = "bench/compare_builds.py --before BEFORE" + (" --full" if a.full else "") + f" --repeat {a.repeat}"
print(save("compare_builds.json", {"command": cmd, "threads": a.threads, "rows": rows}))
