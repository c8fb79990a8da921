#!/usr/bin/env bash
# Installs the Debian 12 packages hpcm builds, tests and runs with. Idempotent: does nothing
# when everything is already installed. Needs root (or sudo) and apt.
set -euo pipefail
PKGS=(
  build-essential cmake pkg-config
  libgtest-dev googletest libbenchmark-dev
  libinsighttoolkit5-dev
  libcli11-dev libtomlplusplus-dev nlohmann-json3-dev
  libglfw3-dev libimgui-dev libpng-dev libgl1-mesa-dev libgl1-mesa-dri
  python3 python3-matplotlib
  python3-dev pybind11-dev python3-numpy python3-pytest
  python3-setuptools python3-wheel python3-pip python3-venv  # pip install . (pyproject.toml)
  python3-nibabel python3-pydicom python3-pil python3-tqdm python3-scipy plastimatch
  python3-pandas python3-distributed  # python3 -m hpcm.cohort (Dask)
  xvfb xauth
  clang lld libclang-rt-14-dev libomp-14-dev  # libFuzzer harnesses (preset fuzz: clang, lld, OpenMP)
)
missing=()
for p in "${PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PKGS[@]} packages present"
  exit 0
fi
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -q
$SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
