#!/usr/bin/env bash
# Builds the libFuzzer targets of fuzz/ with clang (ASan + UBSan) into build-fuzz/ (or
# $CAIRN_FUZZ_BUILD_DIR) and runs each for SECONDS (default 60) on one core, seeded from
# the bundled data (and ../shared/datasets when present). Installs clang through apt when
# it is missing. A crash stops that fuzzer and leaves its input as build-fuzz/findings/<target>/
# crash-*; the run then exits 1 after the others have run.
#   tools/fuzz.sh [SECONDS] [TARGET...]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
seconds=${1:-60}
shift || true
build=${CAIRN_FUZZ_BUILD_DIR:-$root/build-fuzz}

"$root/tools/setup-deps.sh"
probe='extern "C" int LLVMFuzzerTestOneInput(const char*, unsigned long) { return 0; }'
if ! command -v clang++ >/dev/null ||
   ! echo "$probe" | clang++ -x c++ -fsanitize=fuzzer - -o /dev/null 2>/dev/null; then
  echo "fuzz: installing clang and its runtime (libFuzzer)"
  sudo=()
  [[ $(id -u) -ne 0 ]] && sudo=(sudo)
  export DEBIAN_FRONTEND=noninteractive
  "${sudo[@]}" apt-get update -qq
  "${sudo[@]}" apt-get install -y -qq --no-install-recommends clang libclang-rt-dev >/dev/null
fi

generator=()
command -v ninja >/dev/null && [[ ! -f "$build/Makefile" ]] && generator=(-G Ninja)
CXX=clang++ CC=clang cmake -S "$root" -B "$build" "${generator[@]}" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCAIRN_SANITIZE=address,undefined -DCAIRN_BUILD_FUZZERS=ON -DCAIRN_BUILD_TESTS=OFF \
  -DCAIRN_BUILD_APPS=OFF -DCAIRN_BUILD_PYTHON=OFF >/dev/null
targets=("$@")
if [[ ${#targets[@]} -eq 0 ]]; then
  targets=(fuzz_intrinsics fuzz_settings fuzz_stereo_calib fuzz_depth_image fuzz_point_file
           fuzz_kitti_text fuzz_world fuzz_checkpoint fuzz_rawlog fuzz_detector fuzz_map)
fi
cmake --build "$build" --parallel "$(nproc)" --target "${targets[@]}"

shared=$root/../shared/datasets
seed() {  # seed TARGET FILE...: copies the files that exist into the target's seed corpus
  local dir=$build/seeds/$1
  shift
  mkdir -p "$dir"
  for f in "$@"; do
    [[ -f $f ]] && cp "$f" "$dir/$(echo "$f" | md5sum | cut -c1-12)-$(basename "$f")"
  done
  return 0
}
prefixed() {  # prefixed TARGET BYTE FILE...: seeds whose first byte picks the reader
  local dir=$build/seeds/$1 byte=$2
  shift 2
  mkdir -p "$dir"
  for f in "$@"; do
    [[ -f $f ]] || continue
    { printf "\\x$byte"; head -c 65536 "$f"; } >"$dir/$byte-$(echo "$f" | md5sum | cut -c1-12)"
  done
}
seed fuzz_intrinsics "$root"/datasets/frames/*/intrinsics.yaml "$shared"/rgbd-tum-frame/*.yaml
seed fuzz_settings "$root"/config/*.yaml "$root"/config/sensors/*.yaml \
  "$root"/datasets/sequences/hill_drive/map.yaml
seed fuzz_stereo_calib "$root"/config/sensors/stereo-vehicle.yaml "$shared"/stereo-*/*.yaml \
  "$shared"/stereo-*/*.txt "$shared"/stereo-*/*/*.txt
seed fuzz_depth_image "$root"/datasets/frames/demo/truth.png "$shared"/rgbd-tum-frame/*.png
seed fuzz_world "$root"/datasets/worlds/*.yaml "$root"/datasets/sequences/hill_drive/world.yaml
prefixed fuzz_point_file 00 "$shared"/kitti-seq00-0-10/velodyne/000000.bin
prefixed fuzz_point_file 02 "$root"/tests/data/malformed/txt/* 2>/dev/null || true
prefixed fuzz_kitti_text 00 "$shared"/kitti-seq00-0-10/calib.txt
prefixed fuzz_kitti_text 01 "$shared"/kitti-seq00-0-10/poses.txt
prefixed fuzz_kitti_text 02 "$shared"/kitti-seq00-0-10/times.txt
seed fuzz_rawlog /usr/share/mrpt/datasets/tests_rgbd.rawlog
mkdir -p "$build/seeds/fuzz_checkpoint" "$build/seeds/fuzz_detector" "$build/seeds/fuzz_map"
# A small valid point scan and PLY for the point reader, made here.
python3 - "$build/seeds/fuzz_point_file" <<'PY'
import math, struct, sys, os
d = sys.argv[1]
pts = [(8*math.cos(a/50*math.pi), 8*math.sin(a/50*math.pi), -1.5) for a in range(100)]
open(os.path.join(d, 'bin-small'), 'wb').write(b'\x00' + b''.join(struct.pack('<4f', *p, 0.5) for p in pts))
head = 'ply\nformat binary_little_endian 1.0\nelement vertex 100\nproperty float x\nproperty float y\nproperty float z\nproperty ushort ring\nend_header\n'
open(os.path.join(d, 'ply-binary'), 'wb').write(b'\x01' + head.encode() + b''.join(struct.pack('<3fH', *p, i % 16) for i, p in enumerate(pts)))
open(os.path.join(d, 'ply-ascii'), 'wb').write(b'\x01' + ('ply\nformat ascii 1.0\nelement vertex 100\nproperty float x\nproperty float y\nproperty float z\nend_header\n' + ''.join('%g %g %g\n' % p for p in pts)).encode())
open(os.path.join(d, 'txt'), 'wb').write(b'\x02' + ''.join('%g %g %g 0.5\n' % p for p in pts).encode())
open(os.path.join(d, 'label'), 'wb').write(b'\x04' + b''.join(struct.pack('<I', 1) for p in pts))
PY
python3 -c "import sys; sys.stdout.buffer.write(bytes([15, 11, 150, 60, 70, 100]) + bytes(range(256)) * 2)" \
  >"$build/seeds/fuzz_detector/ramp"

# A real checkpoint: the bundled drive, interrupted (SIGINT) once its first checkpoint is
# written (needs the cairn command of a normal build; skipped when there is none).
cairn=${CAIRN_EXE:-$root/build/apps/cairn}
if [[ -x $cairn && ! -f $build/seeds/fuzz_checkpoint/map.checkpoint ]]; then
  tmp=$(mktemp -d)
  "$cairn" map --rawlog "$root/datasets/sequences/hill_drive/sequence.rawlog" \
    --checkpoint-every 1 --out "$tmp/out" >/dev/null 2>&1 &
  pid=$!
  for _ in $(seq 300); do
    [[ -f $tmp/out/map.checkpoint ]] && break
    sleep 0.1
  done
  kill -INT "$pid" 2>/dev/null || true
  wait "$pid" 2>/dev/null || true
  [[ -f $tmp/out/map.checkpoint ]] && { printf '\x01'; cat "$tmp/out/map.checkpoint"; } \
    >"$build/seeds/fuzz_checkpoint/map.checkpoint"
  rm -rf "$tmp"
fi
# The map's seed: three frames of a wall 3 m ahead of a camera moving forward.
python3 - "$build/seeds/fuzz_map/wall" <<'PY'
import struct, sys
out = bytes([2])
for f in range(3):
    out += bytes([128 + f, 128, 128, 128, 128, 128, 10, 128])
    out += b''.join(struct.pack('<H', 3000 if r < 8 else 1500 + 100 * r) for r in range(12) for c in range(12))
open(sys.argv[1], 'wb').write(out)
PY

export ASAN_OPTIONS="halt_on_error=1:detect_leaks=1:allocator_may_return_null=1"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1"
status=0
for t in "${targets[@]}"; do
  corpus=$build/corpus/$t findings=$build/findings/$t
  mkdir -p "$corpus" "$findings" "$build/seeds/$t"
  echo "=== fuzz: $t for $seconds s"
  if ! "$build/fuzz/$t" "$corpus" "$build/seeds/$t" -max_total_time="$seconds" -max_len=65536 \
      -timeout=10 -rss_limit_mb=2048 -artifact_prefix="$findings/" -print_final_stats=1 \
      >"$build/$t.log" 2>&1; then
    echo "fuzz: $t FOUND A FAILURE, input in $findings/:" >&2
    grep -E "ERROR|SUMMARY|runtime error|Test unit written" "$build/$t.log" | head -5 >&2
    status=1
  fi
  grep -E "stat::number_of_executed_units|stat::new_units_added" "$build/$t.log" | tr '\n' ' '
  echo
done
exit $status
