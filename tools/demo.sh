#!/usr/bin/env bash
# The demo: installs what is missing, builds, and runs `cairn detect` on the bundled frame
# (datasets/frames/demo) with config/default.yaml. Results go to out/demo/.
# Extra arguments go to `cairn detect` (e.g. --method column, --no-rules).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${CAIRN_BUILD_DIR:-$root/build}
frame=$root/datasets/frames/demo
out=$root/out/demo

"$root/tools/setup-deps.sh"
"$root/tools/build.sh" -DCAIRN_BUILD_APPS=ON

cairn=$build/apps/cairn
[[ -x "$cairn" ]] || { echo "demo: $cairn was not built" >&2; exit 1; }
for f in "$frame/depth.png" "$frame/intrinsics.yaml" "$root/config/default.yaml"; do
  [[ -f "$f" ]] || { echo "demo: missing $f" >&2; exit 1; }
done

"$cairn" detect \
  --depth "$frame/depth.png" \
  --intrinsics "$frame/intrinsics.yaml" \
  --config "$root/config/default.yaml" \
  --out "$out" "$@"

echo
echo "demo: results in $out/"
echo "  overlay.png         depth in grey (near bright), kept obstacles blue, rejected red"
echo "  segments_color.png  one colour per segment"
echo "  segments.json       per-segment measures, classes and rejection reasons"
echo "  segments.png        16-bit segment ids; classes.png 0 none / 1 kept / 2 rejected"
