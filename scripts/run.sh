#!/usr/bin/env bash
# Sets up (Debian packages, Release build) and runs the main job: `htfeti solve` on the built-in
# default problem (the membranes contact problem at a moderate size). Extra arguments go to
# `htfeti solve`.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
"$here/scripts/setup.sh"
exec "$here/build/htfeti" solve "$@"
