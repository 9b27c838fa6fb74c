#!/usr/bin/env bash
# Configures a build directory with the Ninja generator: scripts/configure.sh BUILD_DIR [cmake
# arguments]. A directory configured earlier with another generator (Make) loses its CMake cache
# first (CMakeCache.txt and CMakeFiles/), since CMake cannot switch generators in place; the
# next build then compiles everything again.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
build=$1
shift
cache=$build/CMakeCache.txt
if [ -f "$cache" ] && ! grep -q '^CMAKE_GENERATOR:INTERNAL=Ninja$' "$cache"; then
  echo "configure: $build was configured with another generator; reconfiguring it with Ninja"
  rm -rf "$cache" "$build/CMakeFiles"
fi
cmake -G Ninja -S "$here" -B "$build" "$@" >/dev/null
