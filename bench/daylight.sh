#!/usr/bin/env bash
# Daylight timings (docs/benchmarks.md, "Daylight"): the floor plan with its windows opened to the sky and ~530
# work-plane sensors, the glazed window room at several refinements, and the public urban model under an overcast
# sky with both operators (if ../shared/models is there). Usage: bash bench/daylight.sh [BUILD]
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
build="${1:-$here/build}"
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
echo "nproc $(nproc); $(grep -m1 'model name' /proc/cpuinfo)"
/usr/bin/time -f "wall %e s, user %U s, max RSS %M kB" "$build/lambert" solve "$here/examples/floorplan_daylight.obj" \
  -o "$out/fp.vtu" --sky cie-overcast --units photometric --work-plane 0.85 --grid 0.27 \
  --sensors-out "$out/fp_sensors.csv" --stats "$out/fp.json" --threads 2 2>&1 | grep -E "phases|sensors  |daylight|wall"
"$build/lambert" solve "$here/examples/window_room_daylight.obj" -o "$out/wr.vtu" --sky cie-overcast --work-plane 0.85 \
  --grid 0.2 --sensors-out "$out/grid.csv" -q
awk -F, 'NR == 1 {print "x,y,z,nx,ny,nz"} NR > 1 && NR % 4 == 2 {print $1 "," $2 "," $3 ",0,1,0"}' "$out/grid.csv" > "$out/s.csv"
for e in 0 1.0 0.5 0.25; do
  /usr/bin/time -f "max-edge $e: wall %e s" "$build/lambert" solve "$here/examples/window_room_daylight.obj" \
    -o "$out/m$e.vtu" --sky cie-overcast --units photometric --sensors "$out/s.csv" --sensors-out "$out/r$e.csv" \
    --max-edge "$e" 2>&1 | grep -E "patches  |daylight factor|wall"
done
udales="$here/../shared/models/udales_shape.obj"
if [ -f "$udales" ]; then
  for op in hierarchical dense; do
    /usr/bin/time -f "udales $op: wall %e s, max RSS %M kB" "$build/lambert" solve "$udales" -o "$out/u_$op.vtu" \
      --sky cie-overcast --up z --operator "$op" 2>&1 | grep -E "phases|wall"
  done
fi
