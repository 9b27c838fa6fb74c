#!/usr/bin/env python3
"""Performance measurements for docs/performance.md (rerun with this script):
  1. memory bandwidth: a STREAM-like triad, 1 and 2 threads (build/htfeti_stream);
  2. the dual operator on the Table 3 subdomain size (100 x 100 nodes, H_s/h = 99): implicit
     against explicit, setup per subdomain, time per F per subdomain, memory, and the
     bandwidth bound of streaming the factor (implicit) or the dense block (explicit);
  3. strong scaling on a reduced Table 3 case: 1 and 2 threads, 1 and 2 ranks.
Each timing is the median of --repeat runs.

Usage: bench/performance.py [--repeat 3] [--skip-scaling]
Writes bench/results/performance.json and prints markdown tables."""
import argparse
import json
import os
import statistics
import subprocess

from common import ROOT, env, save, solve

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--repeat", type=int, default=3)
p.add_argument("--skip-scaling", action="store_true")
a = p.parse_args()
out = {"command": f"bench/performance.py --repeat {a.repeat}"}

# 1. bandwidth
stream = []
for t in (1, 2):
    r = subprocess.run([os.path.join(ROOT, "build", "htfeti_stream"), "512", "10"], env=env(t),
                       check=True, capture_output=True, text=True)
    stream.append(json.loads(r.stdout))
out["stream"] = stream
print("| threads | triad GB/s (median of 10) |\n|---:|---:|")
for s in stream:
    print(f"| {s['threads']} | {s['triad_gb_s_median']:.2f} |")
bw1 = stream[0]["triad_gb_s_median"] * 1e9

# 2. implicit vs explicit on 100 x 100 subdomains: membranes, n = 396, N_s = 4 (32 subdomains)
print("\n| operator | setup ms/subdomain | F ms/subdomain | bytes streamed/subdomain | "
      "bound ms (1 thread) | MB/subdomain (factor + blocks) | matvecs |")
print("|---|---:|---:|---:|---:|---:|---:|")
ops = {}
for op in ("implicit", "explicit"):
    runs = [solve(["--problem", "membranes", "-n", 396, "--subdomains", 4, "--dual-operator", op],
                  threads=1) for _ in range(a.repeat)]
    r = runs[0]
    ns = r["subdomains"]
    fact = statistics.median(x["timings"]["factorization"] for x in runs) / ns * 1e3
    fper = statistics.median(x["timings"]["F"] / x["F_applications"] for x in runs) / ns * 1e3
    nnz = r["memory"]["factor_nonzeros"] / ns
    if op == "implicit":
        streamed = 2 * nnz * 8  # forward and backward sweep over the factor values
    else:
        streamed = r["memory"]["explicit_mb"] * 1048576 / ns  # F_i stored packed: all read
    mem = (nnz * 8 + r["memory"]["explicit_mb"] * 1048576 / ns) / 1048576
    ops[op] = {"setup_ms_per_subdomain": fact, "F_ms_per_subdomain": fper,
               "bytes_streamed_per_subdomain": streamed, "bound_ms": streamed / bw1 * 1e3,
               "mb_per_subdomain": mem, "runs": runs}
    print(f"| {op} | {fact:.2f} | {fper:.4f} | {streamed / 1e6:.2f} MB | "
          f"{streamed / bw1 * 1e3:.4f} | {mem:.2f} | {r['matvecs']} |")
out["dual_operator"] = ops

# 3. strong scaling: membranes N_s = 32, H_s/h = 32, m = 4
if not a.skip_scaling:
    args = ["--problem", "membranes", "-n", 1024, "--subdomains", 32, "-m", 4]
    print("\n| ranks x threads | total s | setup+factorization s | solve s | speed-up (total) |")
    print("|---|---:|---:|---:|---:|")
    scaling = []
    base = None
    for ranks, threads in ((1, 1), (1, 2), (2, 1)):
        runs = [solve(args, ranks=ranks, threads=threads) for _ in range(a.repeat)]
        tot = statistics.median(x["timings"]["total"] for x in runs)
        fac = statistics.median(x["timings"]["factorization"] + x["timings"]["setup"] for x in runs)
        sol = statistics.median(x["timings"]["solve"] for x in runs)
        base = base or tot
        scaling.append({"ranks": ranks, "threads": threads, "total": tot, "setup": fac,
                        "solve": sol, "runs": runs})
        print(f"| {ranks} x {threads} | {tot:.2f} | {fac:.2f} | {sol:.2f} | {base / tot:.2f} |")
    out["scaling"] = scaling
else:  # keep the scaling section of the last full run
    old = os.path.join(ROOT, "bench", "results", "performance.json")
    if os.path.exists(old):
        with open(old) as f:
            prev = json.load(f)
        if "scaling" in prev:
            out["scaling"] = prev["scaling"]
            out["scaling_command"] = prev.get("command", "")
print("\n" + save("performance.json", out))
