#!/usr/bin/env bash
# ASan + UBSan build of the readers, mesh preparation and output transaction (build-asan-o1/), then: their
# GoogleTest suites (test_readers, test_prepare, test_output_transaction), the replay of every committed
# issue-15 reproducer and a short fuzz run (FUZZ_RUNS mutated inputs, default 1500). Any sanitizer report
# fails the run (halt_on_error, no recovery). Called by scripts/test.sh; counts in docs/reliability.md.
set -euo pipefail
cd "$(dirname "$0")/.."
launcher=()
if command -v ccache >/dev/null; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
cmake -S . -B build-asan-o1 -DCMAKE_BUILD_TYPE=None -DLAMBERT_BUILD_BENCH=OFF "${launcher[@]}" \
  -DCMAKE_CXX_FLAGS="-O1 -g0 -fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer" \
  -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined" -DCMAKE_SHARED_LINKER_FLAGS="-fsanitize=address,undefined" >/dev/null
cmake --build build-asan-o1 -j"$(nproc)" --target sanitize_tests fuzz_readers
export ASAN_OPTIONS=halt_on_error=1:detect_leaks=1:abort_on_error=0
export UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1
build-asan-o1/tests/sanitize_tests --gtest_brief=1
build-asan-o1/tests/fuzz_readers tests/fuzz/corpus --replay tests/fuzz/corpus/regressions
build-asan-o1/tests/fuzz_readers tests/fuzz/corpus --runs "${FUZZ_RUNS:-1500}" --seed "${FUZZ_SEED:-15}" --max-seconds-per-input 20
