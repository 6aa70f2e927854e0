#!/usr/bin/env bash
# The demo: installs what is missing, builds, and runs `cairn map` on the bundled sequence
# (datasets/sequences/hill_drive: a synthetic 36 m drive over a hill past eight obstacles,
# an MRPT rawlog with wheel odometry and IMU), writing the map into out/demo-map/; then
# `cairn detect` on the bundled frame (datasets/frames/demo) into out/demo/.
# Extra arguments go to `cairn map` (e.g. --tilt prior, --window 20).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${CAIRN_BUILD_DIR:-$root/build}
sequence=$root/datasets/sequences/hill_drive
frame=$root/datasets/frames/demo
out_map=$root/out/demo-map
out=$root/out/demo

"$root/tools/setup-deps.sh"
"$root/tools/build.sh" -DCAIRN_BUILD_APPS=ON

cairn=$build/apps/cairn
[[ -x "$cairn" ]] || { echo "demo: $cairn was not built" >&2; exit 1; }
for f in "$sequence/sequence.rawlog" "$sequence/map.yaml" "$sequence/world.yaml" \
         "$frame/depth.png" "$frame/intrinsics.yaml" "$root/config/default.yaml"; do
  [[ -f "$f" ]] || { echo "demo: missing $f" >&2; exit 1; }
done

"$cairn" map \
  --rawlog "$sequence/sequence.rawlog" \
  --config "$sequence/map.yaml" \
  --truth "$sequence/world.yaml" \
  --truth-poses "$sequence/poses_sensor.tum" \
  --out "$out_map" "$@"

echo
echo "demo: the map is in $out_map/"
echo "  overlay.png      the cost grid enlarged: path (blue), map obstacles (boxes, ids),"
echo "                   true object cells (green: where an obstacle rises 0.15 m, cyan: not obstacles)"
echo "  cost.png         the cost grid: white free .. orange 252 (slope, roughness), purple"
echo "                   253 inscribed, red 254 lethal, grey 255 unknown"
echo "  cost.yaml + cost.pgm   the same for nav2's map_server; elevation.tiff (+ .yaml)"
echo "  map.bt, map.ot, obstacles.ot   OctoMap (octovis, bt2vrml); obstacles.json"
echo "  summary.txt, summary.json, frames.csv, poses.tum   figures, per-frame poses"

"$cairn" detect \
  --depth "$frame/depth.png" \
  --intrinsics "$frame/intrinsics.yaml" \
  --config "$root/config/default.yaml" \
  --out "$out" >/dev/null
echo
echo "demo: one frame's detection is in $out/ (overlay.png: kept obstacles blue, their foot light blue, rejected red)"
