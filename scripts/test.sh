#!/usr/bin/env bash
# Second README command: install what the tests need, build the library, the CLI and the tests
# (Release) and run the whole test suite. The benchmarks are built by scripts/bench.sh.
#   scripts/test.sh            Release build in build/, all tests
#   scripts/test.sh --asan     AddressSanitizer + UBSan build in build-asan/, all tests
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install_deps.sh --tests
dir=build
flags=(-DCMAKE_BUILD_TYPE=Release -DCAIRN_BUILD_TESTS=ON -DCAIRN_BUILD_BENCH=OFF)
if [ "${1:-}" = "--asan" ]; then
  dir=build-asan
  # -O1 -g1: sanitizer builds compile much faster and still give line numbers; the PCL peer
  # cross-checks (PCL's own code is not ours to sanitize) and benchmarks are left out.
  flags=(-DCMAKE_BUILD_TYPE=RelWithDebInfo -DCAIRN_BUILD_TESTS=ON "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1" -DCAIRN_SANITIZE=ON
         -DCAIRN_BUILD_BENCH=OFF -DCAIRN_WITH_PEERS=OFF)
fi
jobs=$(nproc)
cmake -S . -B "$dir" -G Ninja "${flags[@]}"
cmake --build "$dir" -j "$jobs"
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
ctest --test-dir "$dir" --output-on-failure -j "$jobs"
