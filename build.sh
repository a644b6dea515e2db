#!/usr/bin/env bash
# psq's one entry point for people and CI:
#   ./build.sh demo       install what is missing, build (Release), run the main job
#   ./build.sh test       install what is missing, build (Release), run the whole test suite
#   ./build.sh sanitize   the same suite built with AddressSanitizer + UBSan
#   ./build.sh fuzz       clang + libFuzzer: build the fuzz targets, run each for 20 s (ctest -L fuzz;
#                         PSQ_FUZZ_SECONDS=N to change; PSQ_FUZZ_TARGETS="fuzz_psq ..." for some)
#   ./build.sh build      just build (Release) into build/
# Dependencies come from Debian 12's packages only.
set -euo pipefail
cd "$(dirname "$0")"

PACKAGES=(cmake g++ make libzstd-dev libdraco-dev libgtest-dev libgmock-dev libbenchmark-dev libmeshoptimizer-dev python3 valgrind)
JOBS=$(nproc 2>/dev/null || echo 2)

install_deps() {
  local missing=()
  for p in "${PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  [ ${#missing[@]} -eq 0 ] && return 0
  if [ "$(id -u)" -eq 0 ]; then
    echo "build.sh: installing ${missing[*]}" >&2
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
  else
    echo "build.sh: missing packages; run as root:" >&2
    echo "  apt-get install -y ${missing[*]}" >&2
    exit 1
  fi
}

configure_build() {  # $1 build dir, rest: cmake options
  local dir=$1; shift
  cmake -S . -B "$dir" -DCMAKE_BUILD_TYPE=Release "$@" >/dev/null
  cmake --build "$dir" -j "$JOBS"
}

cmd=${1:-test}
case "$cmd" in
  build)
    install_deps
    configure_build build
    ;;
  demo)
    install_deps
    configure_build build -DPSQ_BUILD_TESTS=OFF
    out=$(mktemp -d)
    trap 'rm -rf "$out"' EXIT
    echo "== build/psq-meshgen --triangles 200k -o mesh.ply   (a generated test mesh)"
    build/psq-meshgen --triangles 200k -o "$out/mesh.ply" >/dev/null
    echo "== psq convert mesh.ply mesh.psq   (16-bit positions, like draco_encoder -qp 16)"
    build/psq convert "$out/mesh.ply" "$out/mesh.psq"
    echo "== psq info mesh.psq"
    build/psq info "$out/mesh.psq"
    echo "== psq convert mesh.psq back.ply; psq verify mesh.psq"
    build/psq convert "$out/mesh.psq" "$out/back.ply"
    build/psq verify "$out/mesh.psq"
    if build/psq convert --help | grep -q drc; then
      build/psq convert "$out/mesh.ply" "$out/mesh.drc" -q
    fi
    echo "== sizes"
    for f in mesh.ply mesh.psq mesh.drc back.ply; do
      [ -f "$out/$f" ] && printf '%-10s %10d bytes\n' "$f" "$(stat -c %s "$out/$f")"
    done
    ;;
  test)
    install_deps
    configure_build build
    (cd build && ctest --output-on-failure -j "$JOBS")
    ;;
  sanitize)
    install_deps
    # The benchmarks are built and checked by `test`; under the sanitizers
    # only the suite runs, so they are left out (CI time).
    configure_build build-sanitize -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPSQ_SANITIZE=ON -DPSQ_BUILD_BENCH=OFF
    (cd build-sanitize && ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 ctest --output-on-failure -j "$JOBS")
    ;;
  fuzz)
    PACKAGES+=(clang libclang-rt-14-dev)
    install_deps
    CC=clang CXX=clang++ cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPSQ_FUZZ=ON -DPSQ_BUILD_TESTS=OFF -DPSQ_BUILD_BENCH=OFF \
      "-DPSQ_FUZZ_SECONDS=${PSQ_FUZZ_SECONDS:-20}" >/dev/null
    if [ -n "${PSQ_FUZZ_TARGETS:-}" ]; then
      # Only these targets (space-separated), e.g. PSQ_FUZZ_TARGETS=fuzz_psq.
      for target in $PSQ_FUZZ_TARGETS; do cmake --build build-fuzz -j "$JOBS" --target "$target"; done
      (cd build-fuzz && ctest -L fuzz --output-on-failure -j "$JOBS" -R "^($(echo "$PSQ_FUZZ_TARGETS" | tr ' ' '|'))\$")
    else
      cmake --build build-fuzz -j "$JOBS"
      (cd build-fuzz && ctest -L fuzz --output-on-failure -j "$JOBS")
    fi
    ;;
  *)
    echo "usage: ./build.sh [demo|test|sanitize|fuzz|build]" >&2
    exit 2
    ;;
esac
