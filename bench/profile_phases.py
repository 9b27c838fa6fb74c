#!/usr/bin/env python3
"""Where one phase of `htfeti solve` spends its time: `perf record` (Debian package
linux-perf) samples the whole run with CLOCK_MONOTONIC timestamps, the solve prints its
progress lines (timed here on the same clock) and its report gives the phase lengths; the
samples inside the chosen phase's window are counted by symbol.

Windows: solve = from "setup done" to the reconstruction (the dual solve); assembly = the timings.setup seconds (assembly and constraints) before the
factorization; coarse = the timings.coarse_problem seconds before "setup done" (the coarse space,
its factor, lambda~ and the preconditioner's weights end the setup); factorization = the
timings.factorization seconds before those; output = after
"reconstruction done", timings.checks later, for timings.output seconds; checks = the
timings.checks seconds after "reconstruction done".

With --kernel-callers the samples carry call chains (perf -g) and those taken in the kernel
(page faults, page zeroing, TLB flushes, copies into the page cache) are also counted by the
first function of ours (or of a library) above them: who makes the kernel work. --phase all
takes the whole run.

Usage: bench/profile_phases.py [--phase output|checks|assembly|factorization|coarse|solve|all] [--kernel-callers]
                               [--threads 2] [--top 12] [-- htfeti solve arguments]
Default case: Table 3 at full size, m = 1, with the VTU written. Prints the shares of the top
symbols (perf's sampling: about +-1 percentage point at the default case's sample counts),
with anonymous namespaces written {anon}."""
import argparse
import collections
import json
import re
import os
import subprocess
import tempfile
import time

from common import BIN, env

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--phase", choices=["output", "checks", "assembly", "factorization", "coarse", "solve", "all"], default="output")
p.add_argument("--kernel-callers", action="store_true",
               help="count kernel samples by the first user-space function above them")
p.add_argument("--threads", type=int, default=2)
p.add_argument("--top", type=int, default=12)
p.add_argument("args", nargs="*")
a = p.parse_args()
args = a.args or ["--problem", "membranes", "-n", "3168", "--subdomains", "32", "-m", "1"]

with tempfile.TemporaryDirectory(dir=os.environ.get("HTFETI_BENCH_TMP")) as d:
    data, report = os.path.join(d, "perf.data"), os.path.join(d, "r.json")
    cmd = ["perf", "record", "-q", "-k", "CLOCK_MONOTONIC", "-F", "499",
           *(["-g"] if a.kernel_callers else []), "-o", data, "--", BIN,
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
    if a.phase == "all":
        lo, hi = 0.0, float("inf")
    elif a.phase == "coarse":  # the last part of the setup
        hi = marks["setup done"]
        lo = hi - t["coarse_problem"]
    elif a.phase == "factorization":
        hi = marks["setup done"] - t["coarse_problem"]
        lo = hi - t["factorization"]
    elif a.phase == "solve":  # the dual solve: after the setup, before the reconstruction
        lo = marks["setup done"]
        hi = marks["reconstruction done"] - t["reconstruction"]
    elif a.phase == "assembly":  # assembly and the constraints, before the factorization
        hi = marks["setup done"] - t["coarse_problem"] - t["factorization"]
        lo = hi - t["setup"]
    else:
        lo = marks["reconstruction done"] + (t["checks"] if a.phase == "output" else 0.0)
        hi = lo + (t["output"] if a.phase == "output" else t["checks"])
    out = subprocess.run(["perf", "script", "-i", data, "-F", "time,ip,sym"],
                         capture_output=True, text=True).stdout
counts, callers = collections.Counter(), collections.Counter()


def symbol(name):
    """A symbol as printed: anonymous namespaces written {anon} (their parenthesis would cut it)."""
    return name.replace("(anonymous namespace)", "{anon}").strip()


if a.kernel_callers:
    # Samples are blocks: a header line (time), then one line per frame (ip symbol), leaf first.
    for block in out.split("\n\n"):
        lines = [x.strip() for x in block.strip().splitlines() if x.strip()]
        if not lines:
            continue
        try:
            ts = float(lines[0].split()[0].rstrip(":"))
        except (ValueError, IndexError):
            continue
        if not lo <= ts < hi:
            continue
        frames = [x.split(None, 1) for x in lines[1:]]
        frames = [(f[0], symbol(re.sub(r"\s+\(.*\)$", "", f[1])) if len(f) > 1 else "[unknown]")
                  for f in frames]
        if not frames:
            continue
        counts[frames[0][1]] += 1
        if frames[0][0].startswith("ffff"):  # a kernel address: find the caller of ours
            user = next((sym for ip, sym in frames if not ip.startswith("ffff")), "[kernel only]")
            callers[user] += 1
else:
    for line in out.splitlines():
        parts = line.split(None, 2)  # time: ip symbol
        if len(parts) < 2:
            continue
        try:
            ts = float(parts[0].rstrip(":"))
        except ValueError:
            continue
        if lo <= ts < hi:
            counts[symbol(parts[2]).split("(")[0].strip() if len(parts) > 2 else "[unknown]"] += 1
total = sum(counts.values())
span = "the whole run" if a.phase == "all" else f"{hi - lo:.2f} s"
print(f"phase {a.phase}: {span}, {total} samples")
for sym, n in counts.most_common(a.top):
    print(f"  {100.0 * n / total:5.1f}%  {sym[:100]}")
if a.kernel_callers:
    k = sum(callers.values())
    print(f"in the kernel: {100.0 * k / max(total, 1):.1f}% of the samples; by the caller above it:")
    for sym, n in callers.most_common(a.top):
        print(f"  {100.0 * n / total:5.1f}%  {sym[:100]}")
