#!/usr/bin/env bash
# The whole test suite: installs what is missing, builds, runs every test with CTest.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
bash scripts/build.sh
# ASan + UBSan build of the readers, preparation and output transaction, with the issue-15 reproducers and a
# short fuzz run (docs/reliability.md). LAMBERT_SKIP_SANITIZE=1 skips it. Runs first, so that CTest's summary
# of the whole suite is what the run ends with.
if [ "${LAMBERT_SKIP_SANITIZE:-0}" != 1 ]; then bash scripts/sanitize.sh; fi
ctest --test-dir build --output-on-failure -j"$(nproc)" --timeout 600
