#!/usr/bin/env bash
# The newcomer's first command: install dependencies, build, and solve the bundled Cornell box.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
bash scripts/build.sh
mkdir -p out
./build/lambert solve examples/cornell_box_fine.obj -o out/cornell_box.vtu --stats out/cornell_box.json
echo
echo "Wrote out/cornell_box.vtu: open it in ParaView (paraview out/cornell_box.vtu), color by 'radiance'."
