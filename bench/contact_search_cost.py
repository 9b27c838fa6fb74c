#!/usr/bin/env python3
"""The cost of contact between bodies in the setup: the punch on a block
(examples/punch-on-block.toml) with its meshes made finer (punch-on-block.geo with n = 60,
m = 55: 3,136 mortar rows), `htfeti solve --dry-run` (reads, partitions and builds the model,
the contact search and the mortar integrals included; no factorization) with and without the
[[contact]] pair, medians of 3 wall times.

Usage: bench/contact_search_cost.py [--n 60] [--m 55] [--out contact_search_cost.json]
Writes bench/results/OUT."""
import argparse
import os
import re
import statistics
import subprocess
import tempfile
import time

from common import BIN, ROOT, save

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--n", type=int, default=60)
p.add_argument("--m", type=int, default=55)
p.add_argument("--out", default="contact_search_cost.json")
a = p.parse_args()
with tempfile.TemporaryDirectory() as tmp:
    msh = os.path.join(tmp, "pb.msh")
    subprocess.run(["gmsh", os.path.join(ROOT, "examples", "meshes", "punch-on-block.geo"), "-3",
                    "-setnumber", "n", str(a.n), "-setnumber", "m", str(a.m), "-format", "msh41",
                    "-o", msh], check=True, stdout=subprocess.DEVNULL)
    with open(os.path.join(ROOT, "examples", "punch-on-block.toml")) as f:
        text = re.sub(r'file = "meshes/[^"]+"', f'file = "{msh}"', f.read())
    variants = {"with pair": text, "without pair": re.sub(r"\[\[contact\]\][^\[]*", "", text)}
    times, rows = {}, None
    for name, t in variants.items():
        path = os.path.join(tmp, "p.toml")
        with open(path, "w") as f:
            f.write(t)
        runs = []
        for _ in range(3):
            t0 = time.perf_counter()
            done = subprocess.run([BIN, "solve", path, "--dry-run"], capture_output=True,
                                  text=True, check=True)
            runs.append(time.perf_counter() - t0)
            m = re.search(r'"rows": (\d+)', done.stdout)
            if m:
                rows = int(m.group(1))
        times[name] = statistics.median(runs)
print(f"punch on a block, n = {a.n}, m = {a.m}: {rows} mortar rows; dry run "
      f"{times['with pair']:.2f} s with the pair, {times['without pair']:.2f} s without "
      f"(medians of 3)")
print(save(a.out, {"command": f"bench/contact_search_cost.py --n {a.n} --m {a.m}", "rows": rows,
                   "seconds": times}))
