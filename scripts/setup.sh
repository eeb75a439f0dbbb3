#!/usr/bin/env bash
# Installs every Debian 12 package that rangebayes' build, tests, benchmarks and fuzzers need.
# Idempotent: installs only what is missing and says what. Works as root or through sudo.
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config git
  libeigen3-dev          # linear algebra (core, bayes)
  libopencv-dev          # calibration, rectification, SGBM, image I/O
  libpcl-dev             # robust model fitting (SAC), kd-trees
  libflann-dev           # nearest neighbours in metrics
  libtbb-dev             # parallel loops
  libcli11-dev           # command line
  nlohmann-json3-dev     # JSON output
  libv4l-dev             # V4L2 cameras
  libcamera-dev          # libcamera cameras
  libgtest-dev libgmock-dev  # tests
  libbenchmark-dev       # bench/
  libcgal-dev            # bench/ only: quadric edge collapse and VSA as decimation references
  clang libclang-rt-14-dev   # libFuzzer targets
  slurmctld slurmd slurm-client munge  # batch/: the test's and bench's throw-away loopback Slurm cluster
  pybind11-dev python3-dev python3-numpy   # the Python module (python/)
  python3-pytest python3-matplotlib python3-open3d   # its tests, examples and Open3D interop
  python3-scipy          # bench/real_scan_pairs.py: nearest neighbours for scoring against the reference scan
  python3-venv python3-pip python3-setuptools python3-wheel   # pip install --no-build-isolation .
  libboost-dev           # console: HTTP/WebSocket server (Boost.Beast, header-only)
  libjs-three            # console: the page's 3D view (served by the process, no CDN)
  chromium               # console: the browser test (headless)
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#packages[@]} packages already installed"
  exit 0
fi

echo "setup: installing ${missing[*]}"
if [ "$(id -u)" -eq 0 ]; then
  as_root=()
elif command -v sudo >/dev/null 2>&1; then
  as_root=(sudo)
else
  echo "setup: error: need root or sudo to install: ${missing[*]}" >&2
  exit 1
fi
export DEBIAN_FRONTEND=noninteractive
"${as_root[@]}" apt-get update -q
"${as_root[@]}" apt-get install -y -q --no-install-recommends "${missing[@]}"
echo "setup: done"
