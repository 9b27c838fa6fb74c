#!/usr/bin/env python3
"""Buffered writes into the page cache with and without memory held: `dd bs=1M` (no direct
I/O) of --mb MiB into HTFETI_BENCH_TMP (or the system's temporary directory; /dev/shm for
tmpfs), alone and while this script holds --hold-gb GiB of touched memory, as a solve holds its
matrices and factors while it writes its VTU. On a virtual machine whose host takes back the
guest's free pages (free page reporting), the page cache then has to come from pages the host
must back again, and the writes slow down to the rate the host gives fresh pages; alone, dd
mostly reuses pages freed a moment ago. Cases interleaved, --repeat times.

Usage: bench/fresh_pages.py [--mb 1882] [--hold-gb 14] [--repeat 3] [--out fresh_pages.json]"""
import argparse
import os
import statistics
import subprocess
import tempfile
import time

from common import save

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--mb", type=int, default=1882)
p.add_argument("--hold-gb", type=float, default=14)
p.add_argument("--repeat", type=int, default=3)
p.add_argument("--out", default="fresh_pages.json")
a = p.parse_args()


def dd(directory):
    f = os.path.join(directory, "z")
    t0 = time.perf_counter()
    subprocess.run(["dd", "if=/dev/zero", f"of={f}", "bs=1M", f"count={a.mb}"], check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    dt = time.perf_counter() - t0
    os.unlink(f)
    return dt


def held(directory):
    block = bytearray(int(a.hold_gb * (1 << 30)))
    for i in range(0, len(block), 4096):  # touch every page
        block[i] = 1
    dt = dd(directory)
    del block
    return dt


runs = {"alone": [], f"holding {a.hold_gb:g} GiB": []}
with tempfile.TemporaryDirectory(dir=os.environ.get("HTFETI_BENCH_TMP")) as d:
    for rep in range(a.repeat):
        for name, f in zip(runs, (dd, held)):
            s = f(d)
            runs[name].append(s)
            print(f"{name:20s} {s:.2f} s ({a.mb / 1024 / s:.2f} GB/s)", flush=True)
summary = {k: {"median_s": statistics.median(v), "runs_s": v} for k, v in runs.items()}
for k, v in summary.items():
    print(f"{k:20s} median {v['median_s']:.2f} s")
save(a.out, {"command": f"bench/fresh_pages.py --mb {a.mb} --hold-gb {a.hold_gb:g} "
             f"--repeat {a.repeat}", "directory": os.environ.get("HTFETI_BENCH_TMP", "(tmp)"),
             "summary": summary})
