#!/usr/bin/env python3
"""The VTU output against the disk: `htfeti solve ... --vtu` (the report's timings.output and
output_mb) and, right after each solve, `dd if=/dev/zero bs=1M` of the same size into the page
cache of the same directory and `dd bs=4M oflag=direct` to the disk. With --before BINARY an
older build runs interleaved with this one (before, after, before, after, ...), so both see the
same hours of this shared VM; with --modes this build runs with each --vtu-io mode in turn.

Usage: bench/vtu_output.py [--before BINARY | --modes buffered direct] [--repeat 3] [--threads 2]
                           [--out FILE] [-- htfeti solve arguments]
Default case: the paper's Table 3 at full size with m = 1 (membranes, n = 3168, 32 x 32
subdomains per membrane: 2.3 GB of VTU). Writes bench/results/vtu_output.json (or --out):
per build the medians of seconds, MB and GB/s, and the dd seconds of the same runs."""
import argparse
import os
import statistics
import subprocess
import tempfile
import time

from common import BIN, save, solve

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--before", help="an older htfeti binary, run interleaved with this one")
p.add_argument("--modes", nargs="+", choices=["auto", "buffered", "direct"],
               help="this build with each --vtu-io mode, interleaved (instead of --before)")
p.add_argument("--repeat", type=int, default=3)
p.add_argument("--threads", type=int, default=2)
p.add_argument("--out", default="vtu_output.json")
p.add_argument("args", nargs="*", help="htfeti solve arguments (after --)")
a = p.parse_args()
args = a.args or ["--problem", "membranes", "-n", 3168, "--subdomains", 32, "-m", 1]


def dd(mb, direct=False):
    """Seconds for dd to write mb MiB of zeros into the page cache of the bench's directory
    (direct: to the disk by direct I/O, 4 MiB blocks, oflag=direct)."""
    with tempfile.TemporaryDirectory(dir=os.environ.get("HTFETI_BENCH_TMP")) as d:
        t0 = time.perf_counter()
        how = ["bs=4M", f"count={int(mb / 4 + 1)}", "oflag=direct"] if direct else \
            ["bs=1M", f"count={int(mb + 1)}"]
        subprocess.run(["dd", "if=/dev/zero", f"of={os.path.join(d, 'z')}", *how], check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        return time.perf_counter() - t0


builds = {"after": (BIN, [])}
if a.before:
    builds = {"before": (a.before, []), "after": (BIN, [])}
if a.modes:
    builds = {m: (BIN, ["--vtu-io", m]) for m in a.modes}
runs = {k: [] for k in builds}
for rep in range(a.repeat):
    for name, (binary, extra) in builds.items():
        r = solve(args + extra, threads=a.threads, binary=binary, vtu=True)
        mb = r["output_mb"]
        d, dd_direct = dd(mb), dd(mb, direct=True)
        runs[name].append({"output_s": r["timings"]["output"], "output_mb": mb, "dd_s": d,
                           "dd_direct_s": dd_direct, "output_io": r.get("output_io"),
                           "steal_fraction": r["steal_fraction"],
                           "assembly_s": r["timings"]["assembly"], "checks_s": r["timings"]["checks"],
                           "total_s": r["timings"]["total"], "wall_s": r["wall_seconds"],
                           "objective": r["objective"]})
        print(f"{name} {rep + 1}: {mb:.0f} MB in {r['timings']['output']:.2f} s "
              f"({mb / 1024 / r['timings']['output']:.2f} GB/s, {r.get('output_io')}); dd {d:.2f} s, "
              f"direct {dd_direct:.2f} s; "
              f"steal {r['steal_fraction']:.3f}", flush=True)
summary = {}
for name, rs in runs.items():
    s = statistics.median(x["output_s"] for x in rs)
    mb = statistics.median(x["output_mb"] for x in rs)
    summary[name] = {"median_output_s": s, "median_output_mb": mb, "median_gb_per_s": mb / 1024 / s,
                     "median_dd_s": statistics.median(x["dd_s"] for x in rs),
                     "median_dd_direct_s": statistics.median(x["dd_direct_s"] for x in rs),
                     "median_checks_s": statistics.median(x["checks_s"] for x in rs),
                     "median_assembly_s": statistics.median(x["assembly_s"] for x in rs),
                     "median_wall_s": statistics.median(x["wall_s"] for x in rs), "runs": rs}
    print(f"{name}: median {s:.2f} s for {mb:.0f} MB ({mb / 1024 / s:.2f} GB/s); "
          f"dd of the same size {summary[name]['median_dd_s']:.2f} s; checks "
          f"{summary[name]['median_checks_s']:.2f} s, assembly {summary[name]['median_assembly_s']:.2f} s, "
          f"process wall {summary[name]['median_wall_s']:.1f} s")
save(a.out, {"command": "bench/vtu_output.py " + (f"--modes {' '.join(a.modes)} " if a.modes else "")
             + " ".join(map(str, args)),
             "before": a.before, "summary": summary})
