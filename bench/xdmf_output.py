#!/usr/bin/env python3
"""The XDMF output (one HDF5 file written by all ranks through MPI-IO) against the VTU output
(one piece per rank and a .pvtu) for the same solve, at several rank counts: the report's
timings.output_xdmf and timings.output, the bytes on disk, medians of --repeat runs.

Usage: bench/xdmf_output.py [--ranks 1 2 4] [--repeat 3] [--out xdmf_output.json]
                            [-- htfeti solve arguments]
Default case: the membranes (Laplace, contact), n = 1024, 32 x 32 subdomains per membrane, one
thread per rank (two for one rank). Writes bench/results/OUT."""
import argparse
import os
import statistics
import tempfile

from common import save, solve

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--ranks", type=int, nargs="+", default=[1, 2, 4])
p.add_argument("--repeat", type=int, default=3)
p.add_argument("--out", default="xdmf_output.json")
p.add_argument("args", nargs="*")
a = p.parse_args()
args = a.args or ["--problem", "membranes", "-n", "1024", "--subdomains", "32"]
rows = []
for ranks in a.ranks:
    row = {"ranks": ranks}
    for kind in ("vtu", "xdmf"):
        seconds, mb = [], []
        for _ in range(a.repeat):
            with tempfile.TemporaryDirectory(dir=os.environ.get("HTFETI_BENCH_TMP")) as d:
                if kind == "vtu":
                    r = solve(args, ranks=ranks, threads=2 if ranks == 1 else 1, vtu=True)
                    seconds.append(r["timings"]["output"])
                    mb.append(r["output_mb"])
                else:
                    x = os.path.join(d, "u.xdmf")
                    r = solve([*args, "--xdmf", x], ranks=ranks, threads=2 if ranks == 1 else 1)
                    seconds.append(r["timings"]["output_xdmf"])
                    mb.append(sum(os.path.getsize(os.path.join(d, f)) for f in os.listdir(d))
                              / 1048576)
        row[kind] = {"seconds": statistics.median(seconds), "mb": statistics.median(mb),
                     "runs": seconds}
    rows.append(row)
    print(f"{ranks} ranks: VTU {row['vtu']['mb']:.0f} MB in {row['vtu']['seconds']:.2f} s, "
          f"XDMF + HDF5 {row['xdmf']['mb']:.0f} MB in {row['xdmf']['seconds']:.2f} s", flush=True)
save(a.out, {"args": args, "repeat": a.repeat, "rows": rows})
