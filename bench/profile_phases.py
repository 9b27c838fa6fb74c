#!/usr/bin/env python3
"""Where one phase of `htfeti solve` spends its time: `perf record` (Debian package
linux-perf) samples the whole run with CLOCK_MONOTONIC timestamps, the solve prints its
progress lines (timed here on the same clock) and its report gives the phase lengths; the
samples inside the chosen phase's window are counted by symbol.

Windows: factorization = from "setup done" back by timings.factorization, output = after
"reconstruction done", timings.checks later, for timings.output seconds; checks = the
timings.checks seconds after "reconstruction done".

Usage: bench/profile_phases.py [--phase output|checks|factorization] [--threads 2] [--top 12]
                               [-- htfeti solve arguments]
Default case: Table 3 at full size, m = 1, with the VTU written. Prints the shares of the top
symbols (perf's sampling: about +-1 percentage point at the default case's sample counts)."""
import argparse
import collections
import json
import os
import subprocess
import tempfile
import time

from common import BIN, env

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--phase", choices=["output", "checks", "factorization"], default="output")
p.add_argument("--threads", type=int, default=2)
p.add_argument("--top", type=int, default=12)
p.add_argument("args", nargs="*")
a = p.parse_args()
args = a.args or ["--problem", "membranes", "-n", "3168", "--subdomains", "32", "-m", "1"]

with tempfile.TemporaryDirectory(dir=os.environ.get("HTFETI_BENCH_TMP")) as d:
    data, report = os.path.join(d, "perf.data"), os.path.join(d, "r.json")
    cmd = ["perf", "record", "-q", "-k", "CLOCK_MONOTONIC", "-F", "499", "-o", data, "--", BIN,
           "solve", *args, "--progress", "--report", report, "--vtu", os.path.join(d, "u.vtu")]
    proc = subprocess.Popen(cmd, env=env(a.threads), stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
    marks = {}
    for line in proc.stderr:
        for key in ("setup done", "reconstruction done"):
            if key in line:
                marks[key] = time.monotonic()
    if proc.wait() != 0:
        raise SystemExit(f"htfeti solve failed ({proc.returncode})")
    with open(report) as f:
        t = json.load(f)["timings"]
    if a.phase == "factorization":
        hi = marks["setup done"]
        lo = hi - t["factorization"]
    else:
        lo = marks["reconstruction done"] + (t["checks"] if a.phase == "output" else 0.0)
        hi = lo + (t["output"] if a.phase == "output" else t["checks"])
    out = subprocess.run(["perf", "script", "-i", data, "-F", "time,ip,sym"],
                         capture_output=True, text=True).stdout
counts = collections.Counter()
for line in out.splitlines():
    parts = line.split(None, 2)  # time: ip symbol
    if len(parts) < 2:
        continue
    try:
        ts = float(parts[0].rstrip(":"))
    except ValueError:
        continue
    if lo <= ts < hi:
        counts[parts[2].split("(")[0].strip() if len(parts) > 2 else "[unknown]"] += 1
total = sum(counts.values())
print(f"phase {a.phase}: {hi - lo:.2f} s, {total} samples")
for sym, n in counts.most_common(a.top):
    print(f"  {100.0 * n / total:5.1f}%  {sym[:100]}")
