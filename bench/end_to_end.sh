#!/usr/bin/env bash
# End-to-end timing (load -> VTK) of the bundled examples, time per phase from `lambert solve --stats`.
# Usage: bash bench/end_to_end.sh [build-dir]   (prints a Markdown table for docs/benchmarks.md)
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${1:-build}/lambert
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
echo "date $(date -u +%F), $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')"
echo
echo "| scene | patches | rays | method | iterations | load s | prepare s | form factors s | solve s | write s | total s |"
echo "|---|---|---|---|---|---|---|---|---|---|---|"
for scene in examples/cornell_box.obj examples/cornell_box_fine.obj examples/room.obj examples/floorplan.obj; do
  "$BIN" solve "$scene" -o "$out/x.vtu" --stats "$out/s.json" --quiet
  python3 - "$scene" "$out/s.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[2])); p = s["phases"]
tot = sum(p.values())
print(f"| `{sys.argv[1]}` | {s['patches']} | {s['form_factors']['rays_cast']} | {s['method']} | {s['iterations']} | "
      f"{p.get('load',0):.4f} | {p.get('prepare',0):.4f} | {p.get('form_factors',0):.3f} | {p.get('solve',0):.4f} | "
      f"{p.get('write',0):.4f} | {tot:.3f} |")
PY
done
