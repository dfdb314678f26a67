#!/usr/bin/env bash
# Regenerates the accuracy/cost study: build, run `lambert study`, plot, and rewrite the tables in
# docs/accuracy.md. Usage: bash scripts/study.sh [--quick]   (full study: 2.5 minutes on a quiet 2-core machine)
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
bash scripts/build.sh
out=docs/study
build/lambert study --out "$out" "$@"
/usr/bin/python3 scripts/plot_study.py "$out/study.csv" --check --out docs/images/study --doc docs/accuracy.md
