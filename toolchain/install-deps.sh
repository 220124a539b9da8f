#!/usr/bin/env bash
# Installs every Debian 12 package rdslam's build and tests need, then a Python virtual
# environment (.venv) with the test helpers (lcm, evo). Idempotent: installs only what is
# missing and says what it installs. Runs as root, or through sudo when not root.
#
# usage: toolchain/install-deps.sh [--no-python]
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
with_python=1
for a in "$@"; do
  case "$a" in
    --no-python) with_python=0 ;;
    -h|--help) sed -n '2,7p' "$0"; exit 0 ;;
    *) echo "install-deps: unknown argument '$a'" >&2; exit 2 ;;
  esac
done

# Build: compiler, cmake, ninja. Libraries: OpenCV 4.6, Eigen 3.4, Ceres 2.1, LCM 1.3,
# libsystemd, yaml-cpp, libjpeg-turbo. Tests: GoogleTest, Google Benchmark, clang-format,
# clang with its libFuzzer and sanitizer runtimes (the fuzz targets, tests/fuzz),
# ffmpeg (real MJPEG/YUYV footage), systemd (systemd-analyze), opencv-doc (sample images and
# vtest.avi), python3-venv.
packages=(
  build-essential cmake ninja-build pkg-config git
  libopencv-dev libeigen3-dev libceres-dev libgoogle-glog-dev libgflags-dev
  liblcm-dev liblcm-bin libglib2.0-dev default-jre-headless
  libsystemd-dev libyaml-cpp-dev libturbojpeg0-dev libjpeg62-turbo-dev zlib1g-dev
  libgtest-dev libgmock-dev libbenchmark-dev clang-format clang libclang-rt-14-dev
  ffmpeg systemd opencv-doc
  python3 python3-venv python3-dev
  chromium
)
# The viewer's end-to-end test (tests/e2e) runs in Debian's chromium through playwright-core
# from the npm registry; node and npm come from Debian unless a node is already installed
# (e.g. a nodesource nodejs, which conflicts with Debian's npm package).
if ! command -v node >/dev/null 2>&1 || ! command -v npm >/dev/null 2>&1; then
  packages+=(nodejs npm)
fi

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if ((${#missing[@]})); then
  if [[ $(id -u) -eq 0 ]]; then
    sudo_cmd=()
  elif command -v sudo >/dev/null 2>&1; then
    sudo_cmd=(sudo)
  else
    echo "install-deps: missing packages: ${missing[*]}" >&2
    echo "install-deps: not root and no sudo: install them as root, then run this again" >&2
    exit 1
  fi
  echo "install-deps: installing ${#missing[@]} Debian packages: ${missing[*]}"
  "${sudo_cmd[@]}" apt-get update -qq || { echo "install-deps: apt-get update failed" >&2; exit 1; }
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends \
    "${missing[@]}" >/dev/null || { echo "install-deps: apt-get install failed for: ${missing[*]}" >&2; exit 1; }
else
  echo "install-deps: all ${#packages[@]} Debian packages present"
fi

# Optional: libcamera-dev builds the libcamera: source (CSI cameras). rdslam builds without
# it, so a failure here is a warning, not an error.
optional=(libcamera-dev)
for p in "${optional[@]}"; do
  if dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    continue
  fi
  if [[ $(id -u) -eq 0 ]]; then
    opt_sudo=()
  elif command -v sudo >/dev/null 2>&1; then
    opt_sudo=(sudo)
  else
    echo "install-deps: optional package $p missing (not root, no sudo): the libcamera: source will not be built" >&2
    continue
  fi
  echo "install-deps: installing optional Debian package $p"
  DEBIAN_FRONTEND=noninteractive "${opt_sudo[@]}" apt-get install -y -qq --no-install-recommends "$p" >/dev/null ||
    echo "install-deps: optional package $p could not be installed: the libcamera: source will not be built" >&2
done

# playwright-core, pinned by tests/e2e/package-lock.json.
if [[ ! -f "$here/tests/e2e/node_modules/playwright-core/package.json" ]]; then
  echo "install-deps: npm ci in tests/e2e (playwright-core for the viewer's browser test)"
  npm ci --prefix "$here/tests/e2e" --no-audit --no-fund --loglevel=error >/dev/null ||
    { echo "install-deps: npm ci in tests/e2e failed" >&2; exit 1; }
fi

if ((with_python)); then
  venv="$here/.venv"
  if [[ ! -x "$venv/bin/python" ]]; then
    echo "install-deps: creating Python virtual environment $venv"
    /usr/bin/python3 -m venv "$venv"
  fi
  need=()
  "$venv/bin/python" -c "import lcm" 2>/dev/null || need+=(lcm)
  "$venv/bin/python" -c "import evo" 2>/dev/null || need+=(evo)
  if ((${#need[@]})); then
    echo "install-deps: installing Python packages into .venv: ${need[*]}"
    "$venv/bin/pip" install -q "${need[@]}" || { echo "install-deps: pip install failed: ${need[*]}" >&2; exit 1; }
  else
    echo "install-deps: Python test helpers present in .venv"
  fi
fi
