#!/usr/bin/env bash
# Installs the Debian packages htfeti needs (when missing) and builds it in Release.
# Usage: scripts/setup.sh [BUILD_DIR]   (default: build)
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$here/build}

pkgs=(cmake g++ ninja-build pkg-config libeigen3-dev libsuitesparse-dev libmetis-dev
      libopenblas0-openmp libopenmpi-dev openmpi-bin libcli11-dev nlohmann-json3-dev
      libgtest-dev libfmt-dev libgmsh-dev gmsh libtomlplusplus-dev libmuparser-dev
      libhdf5-openmpi-dev python3-vtk9 python3-numpy python3-h5py)
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${missing[*]}"
  sudo_cmd=""
  [ "$(id -u)" -ne 0 ] && sudo_cmd="sudo"
  $sudo_cmd apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# CHOLMOD calls the system BLAS/LAPACK; make sure the alternative points at OpenBLAS, OpenMP
# flavour: threads run over subdomains and call BLAS concurrently. Inside an OpenMP parallel
# region this flavour runs single-threaded, and unlike Debian's serial flavour it is safe to call
# from several threads at once (the serial one made CHOLMOD report non-positive-definite
# matrices with 2 threads; docs/performance.md).
arch=$(dpkg-architecture -qDEB_HOST_MULTIARCH 2>/dev/null || echo x86_64-linux-gnu)
for lib in libblas.so.3 liblapack.so.3; do
  alt=/usr/lib/$arch/openblas-openmp/$lib
  if [ -e "$alt" ] && command -v update-alternatives >/dev/null; then
    cur=$(readlink -f /usr/lib/$arch/$lib || true)
    if [ "$cur" != "$(readlink -f "$alt")" ]; then
      ${sudo_cmd:-} update-alternatives --set "$lib-$arch" "$alt" >/dev/null 2>&1 || true
    fi
  fi
done

# Ninja, not Make: it starts compiling a target's sources before the libraries it links are
# built, which keeps both cores busy (docs/method.md "Build").
"$here/scripts/configure.sh" "$build" -DCMAKE_BUILD_TYPE=Release
cmake --build "$build" -j "$(nproc)"
