#!/usr/bin/env python3
"""Wall time of the clean builds that scripts/test.sh makes (the part of CI's time that is not
the tests): the Release build of everything, and the sanitizer build of the suites that
scripts/sanitize.sh runs, each configured from scratch in a temporary directory.

Usage: bench/build_time.py [--configs release sanitize] [--generators Ninja "Unix Makefiles"]
                           [--unity off on] [--debug-info g1 g] [--compilers clang gcc]
                           [--out build_time.json]
--generators: CMake's generator (scripts/configure.sh uses Ninja: Make does not compile a
target's sources until the libraries it links are built, so one core idles while the library's
slowest file compiles).
--unity: the library's unity build (-DHTFETI_UNITY_BUILD, its sources compiled in batches of 10
per translation unit; on by default, as in htfeti's own build, docs/method.md "Build").
--debug-info: the sanitizer build's -g level (-g1: line tables, what the sanitizers' stack
traces print; -g: full debug information).
--compilers: the sanitizer build's compiler (scripts/sanitize.sh takes Clang, GCC where Clang is
missing; the Release build is always GCC's). With Ninja the sum of the compile times of all
steps (compile-seconds, from .ninja_log) is recorded beside the wall time.
Each combination is built once (a clean build takes minutes; run the script again for more
samples). The steal fraction of the VM during each build is recorded. Writes
bench/results/<out>."""
import argparse
import os
import shutil
import subprocess
import tempfile
import time

from common import ROOT, cpu_times, save, steal_fraction

# As scripts/sanitize.sh builds them.
SANITIZE_TARGETS = ["test_fem", "test_qp", "test_tfeti", "test_dual", "test_contact",
                    "test_friction", "test_multibody", "test_preconditioner", "test_options",
                    "test_partitioned"]


def compiler_args(compiler):
    """CMake arguments for the sanitizer build's compiler, as scripts/sanitize.sh gives them."""
    if compiler == "gcc":
        return ["-DCMAKE_CXX_COMPILER=g++"]
    gomp = subprocess.run(["g++", "-print-file-name=libgomp.so"], capture_output=True,
                          text=True, check=True).stdout.strip()
    return ["-DCMAKE_CXX_COMPILER=clang++", "-DOpenMP_CXX_FLAGS=-fopenmp=libgomp",
            "-DOpenMP_CXX_LIB_NAMES=gomp", f"-DOpenMP_gomp_LIBRARY={gomp}"]


def compile_seconds(work):
    """The sum of the build steps' times in the build's .ninja_log, or None (not Ninja)."""
    try:
        with open(os.path.join(work, ".ninja_log")) as f:
            rows = [line.split("\t") for line in f if not line.startswith("#")]
        return round(sum(int(r[1]) - int(r[0]) for r in rows) / 1000, 1)
    except (OSError, ValueError, IndexError):
        return None


def sanitize_flags(debug):
    return (f"-O1 -{debug} -fno-omit-frame-pointer -fsanitize=address,undefined "
            "-fno-sanitize-recover=undefined")


def build(config, generator, unity, debug, jobs, compiler="clang"):
    work = tempfile.mkdtemp(prefix="htfeti-build-")
    try:
        cmake = ["cmake", "-G", generator, "-S", ROOT, "-B", work,
                 f"-DHTFETI_UNITY_BUILD={unity.upper()}"]
        if config == "release":
            cmake.append("-DCMAKE_BUILD_TYPE=Release")
            targets = []
        else:
            cmake += ["-DCMAKE_BUILD_TYPE=Sanitize",
                      f"-DCMAKE_CXX_FLAGS_SANITIZE={sanitize_flags(debug)}",
                      "-DCMAKE_EXE_LINKER_FLAGS=-fsanitize=address,undefined"]
            cmake += compiler_args(compiler)
            targets = ["--target"] + SANITIZE_TARGETS
        c0, t0 = cpu_times(), time.perf_counter()
        subprocess.run(cmake, check=True, stdout=subprocess.DEVNULL)
        subprocess.run(["cmake", "--build", work, "-j", str(jobs)] + targets, check=True,
                       stdout=subprocess.DEVNULL)
        wall = time.perf_counter() - t0
        sanitize = config == "sanitize"
        return {"config": config, "generator": generator, "unity": unity,
                "debug_info": debug if sanitize else None,
                "compiler": compiler if sanitize else "gcc", "jobs": jobs,
                "wall_s": round(wall, 1), "compile_seconds": compile_seconds(work),
                "steal_fraction": steal_fraction(c0, cpu_times())}
    finally:
        shutil.rmtree(work, ignore_errors=True)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--configs", nargs="+", default=["release", "sanitize"],
                   choices=["release", "sanitize"])
    p.add_argument("--generators", nargs="+", default=["Ninja"],
                   choices=["Ninja", "Unix Makefiles"])
    p.add_argument("--unity", nargs="+", default=["on"], choices=["on", "off"])
    p.add_argument("--debug-info", nargs="+", default=["g1"], choices=["g1", "g"])
    p.add_argument("--compilers", nargs="+", default=["clang"], choices=["clang", "gcc"])
    p.add_argument("--jobs", type=int, default=os.cpu_count())
    p.add_argument("--out", default="build_time.json")
    a = p.parse_args()
    runs = []
    print("| config | compiler | generator | unity | -g | wall s | compile-s | steal |")
    print("|---|---|---|---|---|---:|---:|---:|")
    combos = [(c, g, u, d, k) for c in a.configs for g in a.generators for u in a.unity
              for d in (a.debug_info if c == "sanitize" else [None])
              for k in (a.compilers if c == "sanitize" else ["gcc"])]
    for config, generator, unity, debug, compiler in combos:
        r = build(config, generator, unity, debug or "g1", a.jobs, compiler)
        runs.append(r)
        steal = r["steal_fraction"]
        print(f"| {config} | {r['compiler']} | {generator} | {unity} | {r['debug_info'] or '-'} | "
              f"{r['wall_s']} | {r['compile_seconds'] or '-'} | "
              f"{'-' if steal is None else f'{steal:.2f}'} |", flush=True)
    commit = subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"],
                            capture_output=True, text=True).stdout.strip()
    print(save(a.out, {"command": "bench/build_time.py", "commit": commit, "runs": runs}))


if __name__ == "__main__":
    main()
