#!/usr/bin/env bash
# Installs the Debian packages anchormap needs to build, test and run its demo.
# Idempotent and non-interactive: does nothing when every package is present,
# otherwise runs `apt-get update` once and `apt-get install -y` for what is missing.
set -euo pipefail

PACKAGES=(
  build-essential cmake pkg-config clang-format
  liblcm-dev liblcm-bin liblcm-java default-jdk-headless   # bus, lcm-gen, lcm-logplayer, lcm-spy jar
  libeigen3-dev                                             # dense 3x3 blocks and small solves
  libsuitesparse-dev                                        # COLAMD ordering, CHOLMOD factorisation
  libopenblas-serial-dev                                    # single-threaded BLAS for CHOLMOD's supernodal batch steps
  libboost-dev libboost-program-options-dev                 # Asio event loop, option parsing; Beast (viewer)
  nlohmann-json3-dev                                        # the viewer's JSON messages (Boost 1.74 has no Boost.JSON)
  chromium                                                  # headless browser for the viewer's browser test
  libgtest-dev libgmock-dev libbenchmark-dev                # tests and micro-benchmarks
  libpng-dev zlib1g-dev                                     # PNG maps, gzip'd CARMEN logs
  libssl-dev                                                # HMAC-SHA-256 of the auth layer (--key-file)
  libcairo2-dev fonts-dejavu-core                           # map and plot drawing (anchormap-render)
  iproute2 util-linux                                       # ip / unshare for the network-namespace tests; chrt / taskset (record_test)
  clang libclang-rt-dev                                     # the sanitizer pass: clang ASan + UBSan + libFuzzer
  lld                                                       # LLVM's linker: ~170 executables link 3x cheaper than with GNU ld
  time                                                      # GNU time: CPU of each process in tools/bench scripts
)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi

echo "install-deps: installing ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -q
$SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
