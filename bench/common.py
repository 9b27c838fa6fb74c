"""Shared helpers of the benchmark scripts: run `htfeti solve` and collect its report."""
import json
import os
import platform
import resource
import shutil
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# HTFETI_BIN: another binary (e.g. a copy that a rebuild of build/ cannot replace mid-run)
BIN = os.environ.get("HTFETI_BIN") or os.path.join(ROOT, "build", "htfeti")
RESULTS = os.path.join(ROOT, "bench", "results")

# The cube-obstacle of issue 32 as a problem file (bench/cases/cube40_metis64*.toml): n^3 hex8
# cells, the obstacle u_z >= -amp sin(pi x / 50), subdomains N (METIS) or [s, s, s] (a box).
CUBE_OBSTACLE_TOML = """[mesh]
generator = "box"
size = [100.0, 100.0, 100.0]
elements = [{n}, {n}, {n}]
element = "hex8"

[physics]
type = "elasticity"
young = 2.1e7
poisson = 0.3
density = 7850
gravity = [0.0, 0.0, -9.8066]

[[dirichlet]]
group = "x0"
value = [0.0, 0.0, 0.0]

[[contact]]
group = "z0"
direction = [0.0, 0.0, -1.0]
gap = "{amp!r}*sin(pi*x/50)"

[decomposition]
subdomains = {subdomains}
cluster_size = 1

[solver]
rtol = {rtol!r}
"""


# Coefficient jumps (bench/preconditioners.py, bench/dirichlet_storage.py): Laplace on the unit
# square, n x n quad4 cells in 8 x 8 subdomains, and plane-strain elasticity on the plate with a
# hole (examples/meshes/plate-with-hole.msh, {mesh}) in 16 METIS parts; {coef} the coefficient
# field, {m} the cluster size.
JUMP_SQUARE_TOML = """[mesh]
generator = "box"
size = [1.0, 1.0]
elements = [{n}, {n}]
element = "quad4"
[physics]
type = "laplace"
source = 1.0
coefficient = "{coef}"
[[dirichlet]]
group = "x0"
value = 0.0
[decomposition]
subdomains = [8, 8]
cluster_size = {m}
[solver]
rtol = 1e-8
"""
# A 24^3 hex8 cube [0, 100]^3 clamped at x = 0 under its own weight, with a coefficient field
# (placeholders field, split: METIS's N or boxes [sx, sy, sz], rtol).
JUMP_CUBE_TOML = """[mesh]
generator = "box"
size = [100.0, 100.0, 100.0]
elements = [24, 24, 24]
element = "hex8"
[physics]
type = "elasticity"
young = 2.1e7
poisson = 0.3
density = 7850
gravity = [0.0, 0.0, -9.8066]
coefficient = "{field}"
[[dirichlet]]
group = "x0"
value = [0.0, 0.0, 0.0]
[decomposition]
subdomains = {split}
[solver]
rtol = {rtol}
"""

JUMP_PLATE_TOML = """[mesh]
file = "{mesh}"
[physics]
type = "elasticity"
young = 2.1e11
poisson = 0.3
coefficient = "{coef}"
[[dirichlet]]
group = "left"
value = [0.0, 0.0]
[[load]]
group = "right"
traction = [1.0e8, 0.0]
[decomposition]
subdomains = 16
cluster_size = {m}
[solver]
rtol = 1e-8
"""


def env(threads=1):
    e = dict(os.environ)
    e.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
             OMP_NUM_THREADS=str(threads))
    return e


def cpu_times():
    """The machine's CPU time counters (/proc/stat "cpu" line: user ... steal), or None."""
    try:
        with open("/proc/stat") as f:
            return [int(v) for v in f.readline().split()[1:9]]
    except (OSError, ValueError):
        return None


def steal_fraction(before, after):
    """The share of CPU time that the hypervisor gave to other guests between two cpu_times()
    (the "st" column of vmstat): the runs of a shared VM that were slowed by its neighbours."""
    if not before or not after:
        return None
    d = [b - a for a, b in zip(before, after)]
    return d[7] / sum(d) if sum(d) > 0 else 0.0


def cube_obstacle_file(directory, n, amplitude, subdomains, rtol=1e-4):
    """Writes the cube-obstacle problem (CUBE_OBSTACLE_TOML: n^3 hex8 cells, obstacle amplitude,
    subdomains as the problem file's value, e.g. "64" or "[4, 4, 4]") into directory and
    returns its path."""
    path = os.path.join(directory, f"cube_{n}_{amplitude:g}_{subdomains.replace(' ', '')}.toml")
    with open(path, "w") as f:
        f.write(CUBE_OBSTACLE_TOML.format(n=n, amp=amplitude, subdomains=subdomains, rtol=rtol))
    return path


def solve(args, ranks=1, threads=1, extra_env=None, binary=None, vtu=False):
    """Runs htfeti solve (build/htfeti, or `binary`) with the given argument list; returns the
    report as a dict. vtu: also write the VTU output (to a temporary directory beside the report,
    deleted afterwards; the report then has timings.output and output_mb)."""
    binary = binary or BIN
    if not os.path.exists(binary):
        sys.exit(f"{binary} is missing: run scripts/setup.sh first")
    with tempfile.TemporaryDirectory(dir=os.environ.get("HTFETI_BENCH_TMP")) as d:
        report = os.path.join(d, "r.json")
        out = ["--vtu", os.path.join(d, "u.vtu")] if vtu else ["--no-vtu"]
        cmd = [binary, "solve", *map(str, args), "--report", report, *out]
        if ranks > 1:
            cmd = ["mpiexec", "-n", str(ranks), "--oversubscribe", "--bind-to", "none"] + cmd
        e = env(threads)
        if extra_env:
            e.update(extra_env)
        t0, c0, u0 = time.perf_counter(), cpu_times(), resource.getrusage(resource.RUSAGE_CHILDREN)
        done = subprocess.run(cmd, env=e, stdout=subprocess.DEVNULL)
        wall, c1 = time.perf_counter() - t0, cpu_times()
        u1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        # exit 3: not converged; the report is written and says why (a result, not a failure)
        if done.returncode not in (0, 3):
            raise subprocess.CalledProcessError(done.returncode, cmd)
        with open(report) as f:
            r = json.load(f)
        r["wall_seconds"] = wall  # the whole process, output included (added by the bench)
        r["steal_fraction"] = steal_fraction(c0, c1)  # CPU time taken by other guests (bench)
        # the process's CPU seconds in user and kernel mode and its minor page faults (bench;
        # with mpiexec: all ranks and the launcher)
        r["process"] = {"user_s": u1.ru_utime - u0.ru_utime, "system_s": u1.ru_stime - u0.ru_stime,
                        "minor_faults": u1.ru_minflt - u0.ru_minflt}
        return r


def petsc_program(name):
    """Builds bench/NAME.c against PETSc into build/NAME when it is missing or older than its
    source (installing Debian's petsc-dev with apt-get first if PETSc is missing; as root), and
    returns its path."""
    exe = os.path.join(ROOT, "build", name)
    if subprocess.run(["pkg-config", "--exists", "petsc"]).returncode != 0:
        print("installing petsc-dev (Debian) ...", file=sys.stderr)
        subprocess.run(["apt-get", "install", "-y", "--no-install-recommends", "petsc-dev"],
                       check=True, env=dict(os.environ, DEBIAN_FRONTEND="noninteractive"))
    src = os.path.join(ROOT, "bench", name + ".c")
    if not os.path.exists(exe) or os.path.getmtime(exe) < os.path.getmtime(src):
        flags = subprocess.run(["pkg-config", "--cflags", "--libs", "petsc"], check=True,
                               capture_output=True, text=True).stdout.split()
        subprocess.run([shutil.which("mpicc") or "mpicc", "-O3", "-o", exe, src, *flags, "-lm"],
                       check=True)
    return exe


def machine():
    cpu = "unknown"
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return {"cpu": cpu, "cores": os.cpu_count(), "system": platform.platform()}


def save(name, payload):
    os.makedirs(RESULTS, exist_ok=True)
    path = os.path.join(RESULTS, name)
    payload = dict(payload, machine=machine())
    with open(path + ".tmp", "w") as f:
        json.dump(payload, f, indent=1)
    os.replace(path + ".tmp", path)
    return path
