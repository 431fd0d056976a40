#!/usr/bin/env bash
# Installs the Debian (bookworm) packages one use of roe needs, and no more. Idempotent: a no-op when
# everything is present; runs `apt-get update` only when something is missing.
#   scripts/install-deps.sh [PROFILE...] [--dev] [--list]
# Profiles (several may be given; the default is `test`, what CI needs):
#   demo    build `roe` alone and run scripts/demo.sh (make demo): compilers, CMake, the libraries every
#           roe links, matplotlib for the demo's plots. No OpenCV, Ceres or Catch2: CMake builds roe
#           without them (roe refine, roe import realsense and roe infer then say what to install)
#   infer   every command, installed (make install): demo + OpenCV (the image helpers), Ceres (roe
#           refine), LibTorch (the PoET pose head of roe infer)
#   test    build everything and run the whole test suite (make test): infer + Catch2, GNU parallel,
#           Slurm, chromium (roe report's browser test), scipy
#   all     every profile
#   --dev   also the developer tools (formatter, fixture and reference generators, clang + libFuzzer for
#           make fuzz)
#   --list  print the packages of the chosen profiles, one per line, and install nothing
# docs/install.md lists what each profile pulls onto a fresh bookworm machine.
set -euo pipefail

demo=(
  build-essential cmake pkg-config
  libeigen3-dev libfmt-dev nlohmann-json3-dev libcli11-dev          # core, CLI
  liblz4-dev libbz2-dev libyaml-cpp-dev libssl-dev                  # ROS bags, Kalibr YAML, sha256
  libzstd-dev libsqlite3-dev                                        # ROS 2 bags: MCAP zstd chunks, rosbag2 .db3
  zlib1g-dev                                                        # evo result zips
  python3 python3-numpy python3-matplotlib                          # plots (roe eval --plot)
  python3-munkres    # fills matplotlib's fonttools "python3-scipy | python3-munkres": without it apt takes scipy,
                     # whose pythran brings Boost, python3-dev and OpenBLAS headers (25 packages, 45 MB)
)
infer=(
  libopencv-dev                                                     # roe-image, roe-infer (ROE_WITH_OPENCV)
  libceres-dev                                                      # roe refine: the batch MAP, Ceres Solver 2.1 (ROE_WITH_CERES)
  libtorch-dev                                                      # the PoET pose head (roe-infer; ROE_WITH_TORCH)
  libopenblas0-pthread                                              # LibTorch's BLAS: without it the reference BLAS (13x slower GEMMs)
)
test_only=(
  catch2                                                            # the test framework (Catch2 v2)
  parallel slurm-wlm munge                                          # roe sweep: the real-engine tests (GNU parallel, single-node Slurm)
  chromium                                                          # roe report's browser test (tests/cli/test_report_cli.cpp)
  python3-scipy                                                     # eval tests: Euler angles against scipy's Rotation
)
dev=(
  clang-format python3-torch
  clang libclang-rt-14-dev    # make fuzz (scripts/fuzz.sh): libFuzzer, ASan, UBSan; the tests replay the corpora with gcc
  # python3-scipy (in test) also regenerates tests/eval/data/stats_reference.json
)

profiles=()
with_dev=0
list=0
for arg in "$@"; do
  case "$arg" in
    demo | test | infer | all) profiles+=("$arg") ;;
    --dev) with_dev=1 ;;
    --list) list=1 ;;
    -h | --help) sed -n '2,17p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "install-deps: unknown profile or option '$arg' (profiles: demo, test, infer, all; options: --dev, --list)" >&2
       exit 2 ;;
  esac
done
[[ ${#profiles[@]} -eq 0 ]] && profiles=(test)

packages=("${demo[@]}")
for p in "${profiles[@]}"; do
  case "$p" in
    test) packages+=("${infer[@]}" "${test_only[@]}") ;;
    infer) packages+=("${infer[@]}") ;;
    all) packages+=("${infer[@]}" "${test_only[@]}" "${dev[@]}") ;;
  esac
done
[[ $with_dev -eq 1 ]] && packages+=("${dev[@]}")
# Each package once, in the order first named.
mapfile -t packages < <(printf '%s\n' "${packages[@]}" | awk '!seen[$0]++')

if [[ $list -eq 1 ]]; then
  printf '%s\n' "${packages[@]}"
  exit 0
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
echo "install-deps (${profiles[*]}): installing ${missing[*]}" >&2
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
