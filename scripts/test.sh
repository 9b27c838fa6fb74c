#!/usr/bin/env bash
# Sets up (Debian packages, Release build) and runs the whole test suite with CTest, then the
# sanitizer job (scripts/sanitize.sh: ASan + UBSan build, unit and MPI suites under it). On 2
# cores, after the Release build (about 6.5 minutes): CTest about 5 minutes, the sanitizer job
# about 11, 6.5 of them its build (docs/reliability.md, "Open").
# `scripts/test.sh --quick` skips the sanitizer job; other arguments go to ctest.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
quick=0
if [ "${1:-}" = "--quick" ]; then
  quick=1
  shift
fi
"$here/scripts/setup.sh"
# Open MPI refuses to start as root without these.
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
# As many suites at a time as there are cores (the MPI suites declare their ranks as PROCESSORS;
# a 4-rank suite runs alone on a 2-core machine).
(cd "$here/build" && ctest --output-on-failure --timeout 900 -j "$(nproc)" "$@")
if [ "$quick" = 0 ]; then
  echo "sanitizer job (ASan + UBSan):"
  "$here/scripts/sanitize.sh"
fi
