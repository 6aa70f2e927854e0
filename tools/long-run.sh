#!/usr/bin/env bash
# The long run of issue 13: a synthetic drive of FRAMES frames (default 2000: 400 m at 2 m/s,
# 10 frames/s, a 320x240 depth camera) past an obstacle every 5 m, mapped online by
# `cairn map --window 40`, then a report of the process's resident memory and the time per
# frame over the run, in blocks of a tenth of the run: memory must level off once the
# rolling window is full (after the first 40 m, 200 frames) and stay level.
#   tools/long-run.sh [FRAMES] [OUT]   (OUT default build-long/; writes OUT/REPORT.md)
# Uses build/apps/cairn (or $CAIRN_EXE), building it with tools/build.sh when missing.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
frames=${1:-2000}
out=${2:-$root/build-long}
cairn=${CAIRN_EXE:-$root/build/apps/cairn}
python=/usr/bin/python3
[[ -x $cairn ]] || "$root/tools/build.sh"
mkdir -p "$out"

# The world: a drive of frames / 10 * 2 m along gently curving waypoints over rolling,
# rough ground; poles, rocks, trees, crates and bushes 3-6 m off the track on both sides.
"$python" - "$frames" "$out/world.yaml" <<'PY'
import math, random, sys
frames, path = int(sys.argv[1]), sys.argv[2]
length = frames / 10.0 * 2.0 + 20.0
rng = random.Random(13)
waypoints = [[x, round(6.0 * math.sin(x / 60.0), 2)] for x in range(0, int(length) + 10, 10)]
objects = []
kinds = ['pole', 'rock', 'tree', 'box', 'bush']
for i, x in enumerate(range(8, int(length), 5)):
    side = 1 if i % 2 == 0 else -1
    y = 6.0 * math.sin(x / 60.0) + side * rng.uniform(3.0, 6.0)
    kind = kinds[i % len(kinds)]
    name = '%s%d' % (kind, i)
    if kind == 'pole':
        o = '{kind: pole, name: %s, obstacle: true, x: %.2f, y: %.2f, radius: 0.1, height: 1.5}' % (name, x, y)
    elif kind == 'rock':
        o = '{kind: rock, name: %s, obstacle: true, x: %.2f, y: %.2f, radii: [0.6, 0.5, 0.45], height: 0.7}' % (name, x, y)
    elif kind == 'tree':
        o = '{kind: tree, name: %s, obstacle: true, x: %.2f, y: %.2f, radius: 0.25, height: 4.0}' % (name, x, y)
    elif kind == 'box':
        o = '{kind: box, name: %s, obstacle: true, x: %.2f, y: %.2f, size: [1.2, 0.8, 0.8], yaw: %d}' % (name, x, y, rng.randint(0, 90))
    else:
        o = ('{kind: bush, name: %s, obstacle: true, x: %.2f, y: %.2f, radii: [0.8, 0.7, 0.6], '
             'height: 1.0, lumps: 6, seed: %d}') % (name, x, y, i)
    objects.append(o)
with open(path, 'w') as f:
    f.write('description: >\n  The long run of tools/long-run.sh: %d frames over %.0f m, an obstacle every 5 m.\n'
            % (frames, length - 20.0))
    f.write('seed: 13\nterrain:\n  height: 0.0\n  waves:\n'
            '    - {amplitude: 1.0, wavelength: 50, direction: 0, phase: 0}\n'
            '    - {amplitude: 0.6, wavelength: 30, direction: 90, phase: 0}\n'
            '  roughness: {amplitude: 0.02, wavelength: 3, count: 3, seed: 5}\n')
    f.write('camera:\n  width: 320\n  height: 240\n  fx: 260\n  max_range: 30\n  noise:\n'
            '    depth_sigma_per_m2: 0.0005\n    dropout_probability: 0.01\n'
            '    edge_smear_px: 1\n    edge_jump: 0.5\n')
    f.write('views:\n  - {x: 0, y: 0, height: 1.6, heading: 0, pitch: 10, roll: 0, follow_terrain: true}\n')
    f.write('drive:\n  waypoints: [%s]\n' % ', '.join('[%g, %g]' % tuple(w) for w in waypoints))
    f.write('  speed: 2.0\n  frame_rate: 10\n  wheelbase: 1.5\n  track: 1.2\n'
            '  sensor_xyz: [0.5, 0.0, 1.6]\n  sensor_pitch: 10\n  odom_sigma_per_m: 0.01\n'
            '  odom_yaw_sigma_per_m: 0.1\n  imu_sigma: 0.3\n  imu_bias: 0.5\n')
    f.write('objects:\n' + ''.join('  - %s\n' % o for o in objects))
PY

echo "long run: rendering $frames frames"
start=$(date +%s)
if [[ ! -f $out/sequence/sequence.rawlog ]]; then
  rm -rf "$out/sequence.tmp"
  "$cairn" synth --world "$out/world.yaml" --drive --frames "$frames" --out "$out/sequence.tmp"
  mv "$out/sequence.tmp" "$out/sequence"
fi
echo "long run: rendered in $(($(date +%s) - start)) s; mapping"
rm -rf "$out/map"
"$cairn" map --rawlog "$out/sequence/sequence.rawlog" --window 40 --progress-every 100 \
  --out "$out/map"

"$python" - "$out/map/frames.csv" "$out/map/summary.json" "$out/REPORT.md" "$frames" <<'PY'
import csv, json, statistics, sys
rows = list(csv.DictReader(open(sys.argv[1])))
summary = json.load(open(sys.argv[2]))
n = len(rows)
block = max(1, n // 10)
def ms(r):
    return sum(float(r[k]) for k in ('read_ms', 'detect_ms', 'refine_ms', 'fuse_ms'))
lines = ['# Long run: %d frames mapped online (`tools/long-run.sh %s`)' % (n, sys.argv[4]), '',
         '%.0f m driven; rolling window 40 m; %.2f frames/s end to end; peak resident memory %.1f MiB.'
         % (summary['distance_driven_m'], summary['frames_per_s'], summary['peak_rss_mb']), '',
         '| frames | resident memory, MiB (min / max) | of it in use (malloc), MiB | time per frame, ms (median / 95th pct) |',
         '| --- | --- | --- | --- |']
for b in range(0, n, block):
    part = rows[b:b + block]
    rss = [float(r['rss_mb']) for r in part]
    heap = [float(r['heap_mb']) for r in part]
    t = sorted(ms(r) for r in part)
    p95 = t[min(len(t) - 1, int(0.95 * len(t)))]
    lines.append('| %d-%d | %.1f / %.1f | %.1f / %.1f | %.1f / %.1f |'
                 % (int(part[0]['frame']), int(part[-1]['frame']), min(rss), max(rss),
                    min(heap), max(heap), statistics.median(t), p95))
# Growth once the window is full: the least-squares slope of memory over the second half.
half = rows[n // 2:]
xs = [float(r['frame']) for r in half]
ys = [float(r['rss_mb']) for r in half]
mx, my = statistics.mean(xs), statistics.mean(ys)
slope = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / max(1e-9, sum((x - mx) ** 2 for x in xs))
lines += ['', 'Second half of the run: memory grows %.2f MiB per 1,000 frames (least squares), '
          'between %.1f and %.1f MiB.' % (slope * 1000.0, min(ys), max(ys)),
          'Map at the end: %s.' % json.dumps(summary['map'])]
text = '\n'.join(lines) + '\n'
open(sys.argv[3], 'w').write(text)
print(text)
PY
