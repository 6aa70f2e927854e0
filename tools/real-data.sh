#!/usr/bin/env bash
# Runs `cairn detect` on every real recording this project is tested with: the data sets in
# ../shared/datasets (see its README) and Debian's mrpt-common rawlogs; and `cairn map` on
# the KITTI sequence, the one with poses. One folder per run in
# OUT (default out/real), each with the command's outputs and its console report (run.txt);
# OUT/summary.txt collects one line per run. A data set that is absent is skipped, saying so.
# With --figures, the overlays are also copied into datasets/real/figures/ (the gallery of
# datasets/real/REPORT.md). Builds cairn first when needed (tools/build.sh).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${CAIRN_BUILD_DIR:-$root/build}
shared=${CAIRN_SHARED_DATASETS:-$root/../shared/datasets}
mrpt=/usr/share/mrpt/datasets
out=$root/out/real
figures=""
while [[ $# -gt 0 ]]; do
  case $1 in
    --figures) figures=$root/datasets/real/figures; shift ;;
    --out) out=$2; shift 2 ;;
    *) echo "real-data: unknown argument $1 (use --out DIR, --figures)" >&2; exit 2 ;;
  esac
done
cairn=$build/apps/cairn
[[ -x "$cairn" ]] || "$root/tools/build.sh" -DCAIRN_BUILD_APPS=ON
mkdir -p "$out"
[[ -n "$figures" ]] && mkdir -p "$figures"
summary=$out/summary.txt
: >"$summary"

# run NAME NEEDED_PATH FIGURES... -- cairn ARGS...: runs cairn into OUT/NAME; FIGURES are
# output files (relative to OUT/NAME) copied to the gallery as NAME-<file name>.
run() {
  local name=$1 needed=$2
  shift 2
  local copies=()
  while [[ $1 != "--" ]]; do copies+=("$1"); shift; done
  shift
  if [[ ! -e "$needed" ]]; then
    echo "real-data: $name skipped: $needed not found" | tee -a "$summary"
    return
  fi
  local dir=$out/$name
  rm -rf "$dir"
  local start=$SECONDS
  if ! "$cairn" "$@" --out "$dir" >"$out/$name.txt" 2>&1; then
    echo "real-data: $name FAILED (see $out/$name.txt)" | tee -a "$summary"
    return 1
  fi
  mv "$out/$name.txt" "$dir/run.txt"
  local segments  # the run's own summary line: one frame, a rawlog, or a sequence
  segments=$(grep -m1 -E '^\s+(segments|total|map): ' "$dir/run.txt" | sed 's/^ *//' || true)
  [[ -z "$segments" ]] && segments=$(grep -m1 -E 'time per frame' "$dir/run.txt" | sed 's/^ *//' || true)
  echo "$name: ${segments:-done} ($((SECONDS - start)) s)" | tee -a "$summary"
  if [[ -n "$figures" ]]; then
    for f in "${copies[@]}"; do
      [[ -f "$dir/$f" ]] && cp "$dir/$f" "$figures/$name-$(basename "$f")"
    done
  fi
}

real=$root/datasets/real
rellis=$shared/rellis3d-000104
run rellis3d-os1 "$rellis/os1_bin/000104.bin" overlay.png birds_eye.png -- \
  detect --points "$rellis/os1_bin/000104.bin" --sensor OS1-64 \
  --config "$root/config/sensors/os1-64.yaml"
run rellis3d-vlp32c "$rellis/extras/vel000104.bin" overlay.png birds_eye.png -- \
  detect --points "$rellis/extras/vel000104.bin" --sensor VLP-32C \
  --config "$root/config/sensors/vlp-32c.yaml"
kitti=$shared/kitti-seq00-0-10
run kitti-00 "$kitti/velodyne" 000000/overlay.png 000000/birds_eye.png -- \
  detect --kitti "$kitti" --frames 0:10 --config "$root/config/sensors/hdl-64e.yaml"
run kitti-00-map "$kitti/poses.txt" overlay.png -- \
  map --kitti "$kitti" --config "$root/config/sensors/hdl-64e.yaml"
desk=$shared/stereo-desk-foundationstereo
run stereo-desk "$desk/K.txt" overlay.png disparity_color.png -- \
  detect --left "$desk/left.png" --right "$desk/right.png" --stereo-calib "$real/desk-rig.yaml" \
  --config "$real/stereo-desk.yaml"
tum=$shared/rgbd-tum-frame
run rgbd-tum "$tum/TUM_depth.png" overlay.png -- \
  detect --depth "$tum/TUM_depth.png" --intrinsics "$real/tum-kinect.yaml" \
  --config "$root/config/default.yaml"
run octomap-fr079 "$shared/octomap-fr079/scan.dat.bz2" overlay.png birds_eye.png -- \
  detect --points "$shared/octomap-fr079/scan.dat.bz2" --config "$root/config/default.yaml"
run mrpt-kinect "$mrpt/tests_rgbd.rawlog" 000000_OPENNI2/overlay.png -- \
  detect --rawlog "$mrpt/tests_rgbd.rawlog" --config "$root/config/default.yaml" \
  --annotated "$out/tests_rgbd.annotated.rawlog"
run mrpt-vlp16 "$mrpt/test_velodyne_VLP16.rawlog" 000000_Velodyne1_SCAN/birds_eye.png \
  000000_Velodyne1_SCAN/overlay.png -- \
  detect --rawlog "$mrpt/test_velodyne_VLP16.rawlog" --config "$root/config/sensors/vlp-16.yaml"
run mrpt-rotating "$mrpt/rot_scan_velodyne.rawlog" -- \
  detect --rawlog "$mrpt/rot_scan_velodyne.rawlog" --config "$root/config/sensors/vlp-16.yaml"
echo "real-data: done; outputs in $out, one line per run in $summary"
