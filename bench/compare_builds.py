#!/usr/bin/env python3
"""Wall time of two htfeti builds on the same cases (medians), e.g. before and after a change.

The "before" binary is built from an older commit, for example:
    git worktree add /tmp/htfeti-before <commit> && cmake -S /tmp/htfeti-before -B /tmp/htfeti-before/b \
        -DCMAKE_BUILD_TYPE=Release && cmake --build /tmp/htfeti-before/b -j2 --target htfeti_app

Usage: bench/compare_builds.py --before /tmp/htfeti-before/b/htfeti [--after build/htfeti]
           [--repeat 3] [--full] [--threads 2] [--cases membranes metis40 ...] [--out NAME.json]
           [--extra "more solve arguments for every case"]
Cases: membranes n = 1024, N_s = 32, m = 4 with the VTU written (default), and with --full the
Table 3 full size (n = 3168, N_s = 32) for m = 4 (about 10 GB and two minutes per run).
--cases picks among them and the METIS-split cubes of issue 32 (no VTU, so that the phases
compare): metis40 (bench/cases/cube40_metis64.toml), metis80 (cube80_metis512.toml, one run:
about a minute and 7 GB), metis80pre (the same with --mprgp-expansion preconditioned),
metis40a20 and metis80a20 (the same cubes with the obstacle's amplitude A = 20, *_a20.toml),
bracket (examples/bracket.toml, tet4), hertz and hertztet (the strongly graded hex8 Hertz block
and the tet4 one of bench/hertz_cases.py, meshed by gmsh into a temporary directory), metis80dry (the 80^3 cube at A = 20 with --dry-run:
reading, generating and splitting the mesh and planning, nothing set up; wall time only, medians
of --repeat). The builds take turns run by run, so that the drift of a
shared machine falls on both alike. Each row keeps the phase timings of every run.
Writes bench/results/compare_builds.json (or --out)."""
import argparse
import json
import os
import statistics
import subprocess
import tempfile
import time

from common import ROOT, env, save

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--before", required=True)
p.add_argument("--after", default=os.path.join(ROOT, "build", "htfeti"))
p.add_argument("--repeat", type=int, default=3)
p.add_argument("--threads", type=int, default=2)
p.add_argument("--full", action="store_true")
p.add_argument("--cases", nargs="+",
               choices=["membranes", "full", "metis40", "metis80", "metis80pre", "metis40a20",
                        "metis80a20", "bracket", "hertz", "hertztet", "metis80dry"])
p.add_argument("--out", default="compare_builds.json")
p.add_argument("--extra", default="",
               help="more solve arguments for every case, e.g. \"--preconditioner dirichlet\"")
a = p.parse_args()

CASES = {
    "membranes": ("membranes n=1024 N_s=32 m=4, VTU written",
                  ["--problem", "membranes", "-n", "1024", "--subdomains", "32", "-m", "4"], True,
                  a.repeat),
    "full": ("Table 3 full, m=4 (no VTU)",
             ["--problem", "membranes", "-n", "3168", "--subdomains", "32", "-m", "4"], False, 1),
    "metis40": ("cube-obstacle 40^3 split by METIS into 64 (no VTU)",
                [os.path.join(ROOT, "bench", "cases", "cube40_metis64.toml")], False, a.repeat),
    "metis80": ("cube-obstacle 80^3 split by METIS into 512 (no VTU)",
                [os.path.join(ROOT, "bench", "cases", "cube80_metis512.toml")], False, 1),
    "metis80pre": ("cube-obstacle 80^3 split by METIS into 512, preconditioned expansion (no VTU)",
                   [os.path.join(ROOT, "bench", "cases", "cube80_metis512.toml"),
                    "--mprgp-expansion", "preconditioned"], False, 1),
    "metis40a20": ("cube-obstacle 40^3 split by METIS into 64, A = 20 (no VTU)",
                   [os.path.join(ROOT, "bench", "cases", "cube40_metis64_a20.toml")], False,
                   a.repeat),
    "metis80a20": ("cube-obstacle 80^3 split by METIS into 512, A = 20 (no VTU)",
                   [os.path.join(ROOT, "bench", "cases", "cube80_metis512_a20.toml")], False, 1),
    "bracket": ("bracket, tet4, 12 parts (no VTU)",
                [os.path.join(ROOT, "examples", "bracket.toml")], False, a.repeat),
    "metis80dry": ("cube-obstacle 80^3 split by METIS into 512, A = 20, --dry-run (model only)",
                   [os.path.join(ROOT, "bench", "cases", "cube80_metis512_a20.toml"),
                    "--dry-run"], False, a.repeat),
}
names = a.cases or (["membranes", "full"] if a.full else ["membranes"])
if "hertz" in names or "hertztet" in names:  # the Hertz blocks' meshes and problem files
    import hertz_cases
    hertz = hertz_cases.contact_problems(tempfile.mkdtemp())
    CASES["hertz"] = ("graded Hertz block, hex8, strong grading, 16 METIS parts (no VTU)",
                      [hertz[0][1]], False, a.repeat)
    CASES["hertztet"] = ("Hertz block, tet4, 16 METIS parts (no VTU)", [hertz[3][1]], False,
                         a.repeat)
cases = [CASES[n] for n in names]

rows = []
for name, args, vtu, repeat in cases:
    row = {"case": name, "args": args}
    runs = {"before": ([], []), "after": ([], [])}
    dry = "--dry-run" in args  # no report: wall time only
    for _ in range(repeat):
        for label, binary in (("before", a.before), ("after", a.after)):
            walls, reports = runs[label]
            with tempfile.TemporaryDirectory() as d:
                cmd = [binary, "solve", *args, *a.extra.split()]
                if not dry:
                    cmd += ["--report", os.path.join(d, "r.json")]
                    cmd += ["--vtu", os.path.join(d, "u.vtu")] if vtu else ["--no-vtu"]
                t0 = time.perf_counter()
                subprocess.run(cmd, check=True, env=env(a.threads), stdout=subprocess.DEVNULL)
                walls.append(time.perf_counter() - t0)
                if dry:
                    continue
                with open(os.path.join(d, "r.json")) as f:
                    reports.append(json.load(f))
                vtu_bytes = os.path.getsize(os.path.join(d, "u.vtu")) if vtu else 0
    if dry:
        for label, (walls, _) in runs.items():
            row[label] = {"wall_median_s": statistics.median(walls), "walls_s": walls}
        print(f"{name}: before {row['before']['wall_median_s']:.2f} s, after "
              f"{row['after']['wall_median_s']:.2f} s", flush=True)
        rows.append(row)
        continue
    for label, (walls, reports) in runs.items():
        r = reports[0]
        row[label] = {"wall_median_s": statistics.median(walls), "walls_s": walls,
                      "outer": r["outer_iterations"], "matvecs": r["matvecs"],
                      "energy": r["objective"], "timings": r["timings"],
                      "timings_median": {k: statistics.median(q["timings"][k] for q in reports)
                                         for k in r["timings"]},
                      "factor_nonzeros": r["memory"].get("factor_nonzeros"),
                      "peak_rss_mb": r["memory"]["peak_rss_mb_max_rank"], "vtu_bytes": vtu_bytes}
    b, f = row["before"], row["after"]
    print(f"{name}: before {b['wall_median_s']:.2f} s, after {f['wall_median_s']:.2f} s "
          f"(outer {b['outer']}/{f['outer']}, matvecs {b['matvecs']}/{f['matvecs']}, "
          f"energy rel. diff {abs(b['energy'] - f['energy']) / abs(b['energy']):.1e}, "
          f"VTU {b['vtu_bytes'] / 1e6:.0f}/{f['vtu_bytes'] / 1e6:.0f} MB)", flush=True)
    rows.append(row)
cmd = ("bench/compare_builds.py --before BEFORE" + (" --full" if a.full else "") +
       (" --cases " + " ".join(a.cases) if a.cases else "") + f" --repeat {a.repeat}" +
       (f" --extra \"{a.extra}\"" if a.extra else ""))
print(save(a.out, {"command": cmd, "threads": a.threads, "rows": rows}))
