#!/usr/bin/env bash
# Installs exactly the Debian (bookworm) packages roe's build and tests need. Idempotent: a no-op
# when everything is present; runs `apt-get update` only when something is missing.
#   scripts/install-deps.sh          build + test dependencies (what CI needs)
#   scripts/install-deps.sh --dev    also the developer tools (formatter, fuzzer, fixture generators)
set -euo pipefail

packages=(
  build-essential cmake pkg-config
  libeigen3-dev libfmt-dev nlohmann-json3-dev libcli11-dev catch2   # core, CLI, tests
  liblz4-dev libbz2-dev libyaml-cpp-dev libssl-dev                  # ROS bags, Kalibr YAML, sha256
  libzstd-dev libsqlite3-dev                                        # ROS 2 bags: MCAP zstd chunks, rosbag2 .db3
  zlib1g-dev                                                        # evo result zips
  libceres-dev                                                      # roe refine: the batch MAP (Ceres Solver 2.1)
  libopencv-dev libtorch-dev                                        # images, detector, PoET head
  libopenblas0-pthread                                              # LibTorch's BLAS: without it the reference BLAS (13x slower GEMMs)
  python3 python3-numpy python3-matplotlib                          # plots (roe eval --plot)
  parallel slurm-wlm munge                                          # roe sweep: the real-engine tests (GNU parallel, single-node Slurm)
  chromium                                                          # roe report's browser test (tests/cli/test_report_cli.cpp)
  clang libclang-rt-14-dev                                          # fuzz/smoke test: libFuzzer, ASan, UBSan
)
if [[ "${1:-}" == "--dev" ]]; then
  packages+=(clang-format python3-torch)
  packages+=(python3-scipy)  # regenerates tests/eval/data/stats_reference.json (tests do not need it)
fi

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
if [[ ${#missing[@]} -eq 0 ]]; then
  exit 0
fi

SUDO=""
if [[ $(id -u) -ne 0 ]]; then
  if command -v sudo >/dev/null; then SUDO=sudo; else
    echo "install-deps: missing packages (${missing[*]}) and not root; install them or run as root" >&2
    exit 1
  fi
fi
echo "install-deps: installing ${missing[*]}" >&2
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
