#!/usr/bin/env python3
"""The time a process of htfeti takes to start and end, around the work it does.

The test suites start some 600 processes of htfeti and of their own, most of them for a few
milliseconds of work, so their start-up is a large part of the suites' time. Three commands, each
run --repeat times (medians):
  help:  `htfeti solve --help` (MPI started and ended, nothing else);
  tiny:  a 2-subdomain Poisson problem of 16x16 elements on one process;
  mesh:  examples/plate-with-hole.toml on one process (reads a .msh file: loads the Gmsh SDK);
  ranks: the tiny problem on 2 ranks under mpiexec.
each under Open MPI's defaults and under the settings the test suites use (OMPI_MCA_pml=ob1:
no probing for high-speed networks on one machine; OMPI_MCA_ess_singleton_isolated=1: a process
started without mpiexec runs without a runtime daemon).

Usage: bench/startup_time.py [--binary B ...] [--repeat N] [--out NAME.json]
  --binary: one or more htfeti binaries to compare (default: build/htfeti).
"""
import argparse
import os
import statistics
import subprocess
import sys
import time

import common

SUITE_ENV = {"OMPI_MCA_pml": "ob1", "OMPI_MCA_ess_singleton_isolated": "1"}


def commands(binary):
    mpiexec = ["mpiexec", "-n", "2", "--oversubscribe", "--bind-to", "none"]
    tiny = [binary, "solve", "--problem", "poisson2d", "-n", "16", "--subdomains", "2",
            "--no-vtu"]
    return {
        "help": [binary, "solve", "--help"],
        "tiny": tiny,
        "mesh": [binary, "solve", os.path.join(common.ROOT, "examples", "plate-with-hole.toml"),
                 "--no-vtu"],
        "ranks": mpiexec + tiny,
    }


def seconds(cmd, extra, repeat):
    env = common.env(1)
    env.update(extra)
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        done = subprocess.run(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                              cwd="/tmp")
        times.append(time.perf_counter() - t0)
        if done.returncode != 0:
            sys.exit(f"{' '.join(cmd)}: exit {done.returncode}")
    return statistics.median(times)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--binary", nargs="+", default=[common.BIN])
    ap.add_argument("--repeat", type=int, default=9)
    ap.add_argument("--out", default="startup_time.json")
    a = ap.parse_args()
    rows = []
    for binary in a.binary:
        for label, extra in (("Open MPI defaults", {}), ("suite settings", SUITE_ENV)):
            row = {"binary": binary, "environment": label}
            for name, cmd in commands(binary).items():
                row[name] = round(seconds(cmd, extra, a.repeat), 3)
            print(row, flush=True)
            rows.append(row)
    path = common.save(a.out, {"repeat": a.repeat, "unit": "seconds, median", "rows": rows})
    print("wrote", path)


if __name__ == "__main__":
    main()
