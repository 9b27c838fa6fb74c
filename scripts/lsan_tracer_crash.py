#!/usr/bin/env python3
"""Exit 0 if every test that failed in the last ctest run (Testing/Temporary/LastTestsFailed.log
and LastTest.log of the build directory given) failed only because LeakSanitizer's tracer
crashed at exit ("Tracer caught signal 11 ... LeakSanitizer has encountered a fatal error", an
intermittent fault of the sanitizer runtime, google/sanitizers#1353): its suites passed, and no
sanitizer reported an error or a leak. Exit 1 otherwise. Used by scripts/sanitize.sh to run such
suites once more.

Usage: scripts/lsan_tracer_crash.py BUILD_DIR"""
import os
import re
import sys

CRASH = "LeakSanitizer has encountered a fatal error"
REAL = ("ERROR: AddressSanitizer", "ERROR: LeakSanitizer: detected memory leaks", "runtime error:",
        "[  FAILED  ]", "SUMMARY: ")


def main():
    tmp = os.path.join(sys.argv[1], "Testing", "Temporary")
    try:
        failed = [line.split(":", 1)[1].strip()
                  for line in open(os.path.join(tmp, "LastTestsFailed.log")) if ":" in line]
        log = open(os.path.join(tmp, "LastTest.log"), errors="replace").read()
    except OSError:
        return 1
    if not failed:
        return 1
    for name in failed:
        m = re.search(r"\d+/\d+ Testing: " + re.escape(name) + r"\n(.*?)\n\"" + re.escape(name) +
                      r"\" end time", log, re.S)
        if not m:
            return 1
        out = m.group(1)
        if (CRASH not in out or "Tracer caught signal" not in out or "[  PASSED  ]" not in out
                or any(r in out for r in REAL)):
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
