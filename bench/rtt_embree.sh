#!/bin/sh
# RTT at 4×4 antialiasing against Embree 4.4 on the same rays (issue #15's goal beyond the paper):
# 640×480 pixels × 16 stratified jittered samples, pixel-major; rtt and the kd-tree's 4-ray
# packets via rtt_bench (best of 3), Embree via embree-peer with 16-ray packets (one pixel's
# samples per rtcIntersect16) and single rays (median of 3); ROUNDS rounds, the processes
# alternating. Usage (from the repository root):
#   cargo build --release -p raysift --example rtt_bench -p raysift-cli
#   (cd bench/embree-peer && cargo build --release)   # or bench/ci.sh
#   sh bench/rtt_embree.sh [THREADS] [ROUNDS] > out.txt
set -e
T=${1:-1}; ROUNDS=${2:-2}
TGT=${CARGO_TARGET_DIR:-target}
BIN=$TGT/release/examples/rtt_bench; CLI=$TGT/release/raysift
PEER=bench/target/release/embree-peer
S=../shared/scenes; W=$(mktemp -d)
set -- \
  "cornell|$S/CornellBox-Original.obj --eye -0.01,0.995,3.48 --look -0.01,0.995,-0.025 --fov 45" \
  "bunny|$S/bun_zipper.ply --eye -0.0168,0.11,0.251 --look -0.0168,0.11,-0.00154 --fov 27" \
  "sponza|$S/sponza.obj.gz --eye -13,2.5,0 --look 10,4.5,0 --fov 60"
for c in "$@"; do
  name=${c%%|*}; spec=${c#*|}
  # shellcheck disable=SC2086
  $CLI export ${spec%% *} --out "$W/$name-tris.npy" >/dev/null
  # shellcheck disable=SC2086
  $BIN $spec --width 640 --height 480 --aa 4 --threads "$T" --repeat 1 --only-rtt \
    --export-rays "$W/$name-rays.npy" >/dev/null
done
for r in $(seq "$ROUNDS"); do
  for c in "$@"; do
    name=${c%%|*}; spec=${c#*|}
    # shellcheck disable=SC2086
    $BIN $spec --width 640 --height 480 --aa 4 --threads "$T" --repeat 3 --kd-packets 4 |
      grep primary | sed "s/^/round $r $name /"
    for p in 16 1; do
      $PEER --tris "$W/$name-tris.npy" --rays "$W/$name-rays.npy" --packet $p --threads "$T" \
        --repeat 3 | python3 -c "import json,sys; d=json.load(sys.stdin); print('round $r $name embree packet $p trace_ms', round(d['trace_ms'], 1), 'hits', d['hits'])"
    done
  done
done
rm -rf "$W"
