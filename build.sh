#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# psq's one entry point for people and CI:
#   ./build.sh demo       install what is missing, build psq (Release), show it on a generated mesh
#   ./build.sh test       install what is missing, build everything (Release), run the whole test suite
#   ./build.sh sanitize   the same suite built with AddressSanitizer + UBSan
#   ./build.sh fuzz       clang + libFuzzer: build the fuzz targets, run each for 20 s (ctest -L fuzz;
#                         PSQ_FUZZ_SECONDS=N to change; PSQ_FUZZ_TARGETS="fuzz_psq ..." for some)
#   ./build.sh build      just build everything (Release) into build/
# Every command states the CMake options it needs (the cache of an earlier
# command never decides what a later one builds), and a test run that finds
# no tests fails. Dependencies come from Debian 12's packages only.
set -euo pipefail
cd "$(dirname "$0")"

PACKAGES=(cmake g++ make libzstd-dev libdraco-dev libgtest-dev libgmock-dev libbenchmark-dev libmeshoptimizer-dev python3 valgrind gnuplot-nox
          pybind11-dev python3-dev python3-numpy python3-dask python3-distributed python3-pytest)
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

configure() {  # $1 build dir, rest: cmake options
  local dir=$1; shift
  cmake -S . -B "$dir" -DCMAKE_BUILD_TYPE=Release "$@" >/dev/null
}

run_tests() {  # $1 build dir, rest: ctest options
  local dir=$1; shift
  (cd "$dir" && ctest --output-on-failure --no-tests=error -j "$JOBS" "$@")
}

# Everything: the libraries, psq, the Python module, the tests and the
# benchmarks (built so that they keep compiling; bench/ runs them). The
# Python module is built for Debian's /usr/bin/python3, whatever python3
# comes first on PATH.
ALL=(-DPSQ_LTO=ON -DPSQ_BUILD_TESTS=ON -DPSQ_BUILD_BENCH=ON -DPSQ_SANITIZE=OFF -DPSQ_FUZZ=OFF
     -DPSQ_PYTHON=ON -DPython3_EXECUTABLE=/usr/bin/python3)

cmd=${1:-test}
case "$cmd" in
  build)
    install_deps
    configure build "${ALL[@]}"
    cmake --build build -j "$JOBS"
    ;;
  demo)
    install_deps
    # Only what the demo runs: the psq tool and the mesh generator.
    configure build -DPSQ_LTO=ON -DPSQ_BUILD_TESTS=OFF -DPSQ_BUILD_BENCH=OFF -DPSQ_SANITIZE=OFF -DPSQ_FUZZ=OFF \
      -DPSQ_PYTHON=OFF
    cmake --build build -j "$JOBS" --target psq psq-meshgen
    out=$(mktemp -d)
    trap 'rm -rf "$out"' EXIT
    echo "== psq-meshgen --triangles 200k -o mesh.ply"
    echo "   a generated closed surface (many components and handles), as binary PLY"
    build/psq-meshgen --triangles 200k -o "$out/mesh.ply" >/dev/null
    echo "== psq convert mesh.ply mesh.psq"
    echo "   positions quantized to 16 bits (as draco_encoder -qp 16); a mesh this large gets"
    echo "   the fast profile, smaller ones the compact one (--profile; psq convert --help)"
    build/psq convert "$out/mesh.ply" "$out/mesh.psq"
    echo "== psq info mesh.psq"
    echo "   counts, topology and the file's processing sequence (boundary, ops, bits)"
    build/psq info "$out/mesh.psq"
    echo "== psq verify mesh.psq      (decodes everything and checks it)"
    build/psq verify "$out/mesh.psq"
    echo "== psq convert mesh.psq back.ply; psq convert mesh.ply mesh.drc (Draco, for comparison)"
    build/psq convert "$out/mesh.psq" "$out/back.ply"
    build/psq convert "$out/mesh.ply" "$out/mesh.drc" -q
    echo "== sizes"
    for f in mesh.ply mesh.psq mesh.drc back.ply; do
      printf '%-10s %10d bytes\n' "$f" "$(stat -c %s "$out/$f")"
    done
    echo "Next: build/psq --help; README.md has the CLI, the library and how to install."
    ;;
  test)
    install_deps
    configure build "${ALL[@]}"
    cmake --build build -j "$JOBS"
    run_tests build
    ;;
  sanitize)
    install_deps
    # The benchmarks are built and checked by `test`; under the sanitizers
    # only the suite runs, so they are left out (CI time). So is the Python
    # module: instrumented, it would need libasan preloaded into the
    # interpreter, whose own leaks (and numpy's) LeakSanitizer would then
    # report; the library code it calls is what the C++ suite checks here.
    # -O1, as AddressSanitizer advises: GCC compiles the instrumented codec
    # in about half the time it takes at -O2.
    # At -O1 with the sanitizers, GCC 12 warns of uninitialized members
    # inside libstdc++'s std::regex (the tests that use it); the Release
    # build keeps that warning for psq's code.
    configure build-sanitize -DCMAKE_BUILD_TYPE=RelWithDebInfo \
      "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g -DNDEBUG -Wno-maybe-uninitialized" -DPSQ_SANITIZE=ON -DPSQ_BUILD_TESTS=ON -DPSQ_BUILD_BENCH=OFF -DPSQ_FUZZ=OFF \
      -DPSQ_PYTHON=OFF
    cmake --build build-sanitize -j "$JOBS"
    ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 run_tests build-sanitize
    ;;
  fuzz)
    PACKAGES+=(clang libclang-rt-14-dev)
    install_deps
    # (No Python module: the fuzz build instruments everything for libFuzzer.)
    CC=clang CXX=clang++ cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPSQ_FUZZ=ON -DPSQ_BUILD_TESTS=OFF -DPSQ_BUILD_BENCH=OFF \
      -DPSQ_PYTHON=OFF \
      "-DPSQ_FUZZ_SECONDS=${PSQ_FUZZ_SECONDS:-20}" >/dev/null
    if [ -n "${PSQ_FUZZ_TARGETS:-}" ]; then
      # Only these targets (space-separated), e.g. PSQ_FUZZ_TARGETS=fuzz_psq.
      for target in $PSQ_FUZZ_TARGETS; do cmake --build build-fuzz -j "$JOBS" --target "$target"; done
      run_tests build-fuzz -L fuzz -R "^($(echo "$PSQ_FUZZ_TARGETS" | tr ' ' '|'))\$"
    else
      cmake --build build-fuzz -j "$JOBS"
      run_tests build-fuzz -L fuzz
    fi
    ;;
  *)
    echo "usage: ./build.sh [demo|test|sanitize|fuzz|build]" >&2
    exit 2
    ;;
esac
