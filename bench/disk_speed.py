#!/usr/bin/env python3
"""The disk's own speed for direct writes, and whether the VTU writer's pattern matters:
`dd oflag=direct` with 1, 4 and 16 MiB blocks, and 1 MiB direct positioned writes from Python
(as the VTU writer's stages) to one region in order against six regions in turn (as the
writer's arrays) and from two threads. Each case --repeat times, interleaved.

Usage: bench/disk_speed.py [--mb 1882] [--repeat 2] [--out disk_speed.json]
Default size: Table 3 full size's VTU (1,882 MB). The files go to HTFETI_BENCH_TMP (or the
system's temporary directory) and are deleted."""
import argparse
import mmap
import os
import statistics
import subprocess
import tempfile
import threading
import time

from common import save

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--mb", type=int, default=1882)
p.add_argument("--repeat", type=int, default=2)
p.add_argument("--out", default="disk_speed.json")
a = p.parse_args()
MB = 1 << 20
total = a.mb * MB


def dd(directory, bs_mb):
    f = os.path.join(directory, "z")
    t0 = time.perf_counter()
    subprocess.run(["dd", "if=/dev/zero", f"of={f}", f"bs={bs_mb}M", f"count={a.mb // bs_mb}",
                    "oflag=direct"], check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    dt = time.perf_counter() - t0
    os.unlink(f)
    return dt


def pwrites(directory, regions, threads):
    """1 MiB direct writes: `regions` equal parts of the file written in turn, by `threads`."""
    buf = mmap.mmap(-1, MB)  # page-aligned, as O_DIRECT needs
    buf.write(os.urandom(MB))
    f = os.path.join(directory, "w")
    fd = os.open(f, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_DIRECT)
    per = a.mb // regions
    order = [r * per + i for i in range(per) for r in range(regions)]
    view = memoryview(buf)

    def work(k):
        for j in order[k::threads]:
            os.pwrite(fd, view, j * MB)
    t0 = time.perf_counter()
    ts = [threading.Thread(target=work, args=(k,)) for k in range(threads)]
    for t in ts:
        t.start()
    for t in ts:
        t.join()
    os.fsync(fd)
    dt = time.perf_counter() - t0
    os.close(fd)
    os.unlink(f)
    return dt


cases = {"dd 1 MiB": lambda d: dd(d, 1), "dd 4 MiB": lambda d: dd(d, 4),
         "dd 16 MiB": lambda d: dd(d, 16),
         "pwrite 1 region": lambda d: pwrites(d, 1, 1),
         "pwrite 6 regions": lambda d: pwrites(d, 6, 1),
         "pwrite 6 regions, 2 threads": lambda d: pwrites(d, 6, 2)}
runs = {k: [] for k in cases}
with tempfile.TemporaryDirectory(dir=os.environ.get("HTFETI_BENCH_TMP")) as d:
    for rep in range(a.repeat):
        for name, f in cases.items():
            s = f(d)
            runs[name].append(s)
            print(f"{name:28s} {s:.2f} s ({a.mb / 1024 / s:.2f} GB/s)", flush=True)
summary = {k: {"median_s": statistics.median(v), "min_s": min(v), "max_s": max(v), "runs_s": v}
           for k, v in runs.items()}
for k, v in summary.items():
    print(f"{k:28s} median {v['median_s']:.2f} s ({v['min_s']:.2f}-{v['max_s']:.2f})")
save(a.out, {"command": f"bench/disk_speed.py --mb {a.mb} --repeat {a.repeat}", "mb": a.mb,
             "summary": summary})
