#!/usr/bin/env python3
"""Performance measurements for docs/performance.md (rerun with this script):
  1. memory bandwidth: a STREAM-like triad, 1 and 2 threads (build/htfeti_stream);
  2. the dual operator on the Table 3 subdomain size (100 x 100 nodes, H_s/h = 99): implicit
     against explicit, setup per subdomain, time per F per subdomain, memory, and the
     bandwidth bound of streaming the factor (implicit) or the dense block (explicit);
  3. the packed product kernel alone (build/htfeti_packed_product: 1,200 MB of F_i blocks of the
     Table 3 size, far beyond the caches), 1 and 2 threads, double and single, against the triad;
  4. F at scale: the full Table 3 case with m = 1 (2,048 subdomains, 1.3 GB of packed F_i), two
     threads, ms per F against the two-thread triad bound measured just before each run; with
     --before BINARY an older build runs interleaved with this one (before and after);
     --precision single stores the F_i in single precision (--explicit-precision);
  5. strong scaling on a reduced Table 3 case: 1 and 2 threads, 1 and 2 ranks.
Each timing is the median of --repeat runs; with --kernel-before BINARY (an older
build's htfeti_packed_product) section 3 runs both kernels interleaved, --repeat times each.

Usage: bench/performance.py [--repeat 3] [--skip-scaling] [--skip-full] [--before BINARY]
       [--kernel-before BINARY] [--kernel-mb 1200] [--precision double|single]
       [--out performance.json]
Writes bench/results/performance.json (or --out) and prints markdown tables."""
import argparse
import json
import os
import statistics
import subprocess

from common import ROOT, env, save, solve

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--repeat", type=int, default=3)
p.add_argument("--skip-scaling", action="store_true")
p.add_argument("--skip-full", action="store_true", help="skip section 4 (about 50 s per run)")
p.add_argument("--before", default=None, help="an older htfeti binary for section 4")
p.add_argument("--kernel-before", default=None,
               help="an older htfeti_packed_product for section 3, run interleaved")
p.add_argument("--kernel-mb", type=int, default=1200,
               help="MB of blocks in section 3 (a few MB: in cache, the kernel's compute speed)")
p.add_argument("--precision", choices=["double", "single"], default="double",
               help="storage of the F_i in section 4")
p.add_argument("--out", default="performance.json", help="file name under bench/results")
a = p.parse_args()
out = {"command": "bench/performance.py --repeat %d%s%s%s%s%s%s%s" % (
    a.repeat, " --skip-scaling" if a.skip_scaling else "", " --skip-full" if a.skip_full else "",
    " --before BEFORE" if a.before else "",
    " --kernel-before KERNEL_BEFORE" if a.kernel_before else "",
    " --precision single" if a.precision == "single" else "",
    f" --kernel-mb {a.kernel_mb}" if a.kernel_mb != 1200 else "",
    f" --out {a.out}" if a.out != "performance.json" else "")}


def triad(threads):
    r = subprocess.run([os.path.join(ROOT, "build", "htfeti_stream"), "512", "10"],
                       env=env(threads), check=True, capture_output=True, text=True)
    return json.loads(r.stdout)

# 1. bandwidth
stream = [triad(t) for t in (1, 2)]
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

# 3. the packed kernel alone, against the triad of the same thread count measured just before
kernels = [("before", a.kernel_before)] if a.kernel_before else []
kernels.append(("after", os.path.join(ROOT, "build", "htfeti_packed_product")))
print("\n| threads | precision | build | packed product GB/s (median) | triad GB/s (median) | "
      "triad / product |")
print("|---:|---|---|---:|---:|---:|")
kernel = []
for t in (1, 2):
    for prec in ("double", "single"):
        runs = {label: [] for label, _ in kernels}
        for _ in range(a.repeat if a.kernel_before else 1):
            for label, binary in kernels:  # interleaved: the machine's drift hits both alike
                tri = triad(t)["triad_gb_s_median"]
                reps = "10" if a.kernel_mb >= 100 else "200"  # in cache: short, take more
                r = subprocess.run([binary, "396", str(a.kernel_mb), prec, reps], env=env(t),
                                   check=True, capture_output=True, text=True)
                k = json.loads(r.stdout)
                k["triad_gb_s_median"] = tri
                runs[label].append(k)
        for label, ks in runs.items():
            gb = statistics.median(k["gb_s_median"] for k in ks)
            tri = statistics.median(k["triad_gb_s_median"] for k in ks)
            kernel.append({"threads": t, "precision": prec, "build": label, "gb_s_median": gb,
                           "triad_gb_s_median": tri, "runs": ks})
            print(f"| {t} | {prec} | {label} | {gb:.2f} | {tri:.2f} | {tri / gb:.2f} |")
out["packed_kernel"] = kernel

# 4. F at scale: Table 3 full, m = 1, two threads
if not a.skip_full:
    args = ["--problem", "membranes", "-n", 3168, "--subdomains", 32, "-m", 1,
            "--explicit-precision", a.precision]
    builds = [("before", a.before)] if a.before else []
    builds.append(("after", None))
    res = {label: [] for label, _ in builds}
    for _ in range(a.repeat):
        for label, binary in builds:  # interleaved: the machine's drift hits both alike
            tri = triad(2)["triad_gb_s_median"]
            r = solve(args, threads=2, binary=binary)
            res[label].append({"triad_gb_s": tri, "ms_per_F": r["timings"]["F"] /
                               r["F_applications"] * 1e3, "explicit_mb": r["memory"]["explicit_mb"],
                               "F_applications": r["F_applications"], "objective": r["objective"],
                               "report": r})
    print("\n| build | ms per F (median) | packed F_i GB | triad GB/s (median) | bound ms | F / bound |")
    print("|---|---:|---:|---:|---:|---:|")
    full = {}
    for label, runs in res.items():
        ms = statistics.median(x["ms_per_F"] for x in runs)
        tri = statistics.median(x["triad_gb_s"] for x in runs)
        gb = runs[0]["explicit_mb"] * 1048576 / 1e9
        bound = gb / tri * 1e3
        full[label] = {"ms_per_F": ms, "triad_gb_s": tri, "packed_gb": gb, "bound_ms": bound,
                       "ratio": ms / bound, "runs": runs}
        print(f"| {label} | {ms:.1f} | {gb:.2f} | {tri:.2f} | {bound:.1f} | {ms / bound:.2f} |")
    out["F_at_scale"] = full

# 5. strong scaling: membranes N_s = 32, H_s/h = 32, m = 4
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
    old = os.path.join(ROOT, "bench", "results", a.out)
    if os.path.exists(old):
        with open(old) as f:
            prev = json.load(f)
        if "scaling" in prev:
            out["scaling"] = prev["scaling"]
            out["scaling_command"] = prev.get("command", "")
print("\n" + save(a.out, out))
