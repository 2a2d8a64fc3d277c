#!/usr/bin/env bash
# The README's two commands, plus the steps they are made of.
#   ./run.sh demo   install what is missing, build, run the closed-loop demo on the simulated module
#   ./run.sh test   install what is missing, build, run every test (what CI runs)
#   ./run.sh deps | build | bench
set -euo pipefail
cd "$(dirname "$0")"

# Debian 12 packages the build, the tests and the demo need.
PACKAGES=(cmake ninja-build g++ make pkg-config git
          gcc-avr avr-libc binutils-avr avrdude simavr libsimavr-dev libelf-dev
          libeigen3-dev libgtest-dev libgmock-dev libbenchmark-dev
          libusb-1.0-0-dev libbluetooth-dev nlohmann-json3-dev libcli11-dev libfmt-dev
          libcairo2-dev clang libclang-rt-14-dev)

deps() {
  local missing=()
  for p in "${PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  [ ${#missing[@]} -eq 0 ] && return 0
  echo "==> installing Debian packages: ${missing[*]}"
  local sudo=""; [ "$(id -u)" -ne 0 ] && sudo="sudo"
  $sudo apt-get update -q
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -q --no-install-recommends "${missing[@]}"
}

build() {
  echo "==> configuring and building (build/)"
  cmake --preset host >/dev/null
  cmake --build --preset host -j "$(nproc)"
}

case "${1:-}" in
  deps)  deps ;;
  build) deps; build ;;
  test)  deps; build
         echo "==> running every test"
         ctest --preset host ;;
  demo)  deps; build
         echo "==> running the closed-loop demo on the simulated module"
         shift; ./build/bin/btsm demo --out report "$@" ;;
  bench) deps; build; cmake --build --preset host --target bench ;;
  *) echo "usage: $0 demo|test|deps|build|bench" >&2; exit 2 ;;
esac
