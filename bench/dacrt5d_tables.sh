#!/usr/bin/env bash
# Issue #17's tables for dacrt5d (BENCHMARKS.md § "dacrt5d: box splits"): the same batches for
# every contender in one process, contenders alternating, best of --repeat, one thread.
#   bash bench/dacrt5d_tables.sh [OUT.md]        (release build of the example first)
# Scenes from ../shared/scenes (RAYSIFT_SCENES to point elsewhere).
set -euo pipefail
cd "$(dirname "$0")/.."
S=${RAYSIFT_SCENES:-../shared/scenes}
OUT=${1:-bench/results/$(date +%F)-dacrt5d.md}
cargo build --release -q -p raysift --example dacrt5d_bench
B=./target/release/examples/dacrt5d_bench
run() { echo; echo "### $*"; echo; echo '```text'; echo "dacrt5d_bench $*"; echo '```'; echo; "$B" "$@" --counters; }
{
  echo "# dacrt5d tables, $(date -u '+%F %H:%M UTC'), $(git rev-parse --short HEAD)"
  # Culls, stops and the two hybrids on the bunny (the first hybrid's random rays are slow).
  run "$S/bun_zipper.ply" --width 256 --random 65536 --bounces 3 --repeat 2 --threads 1 \
    --tracer bvh --tracer dacrt --tracer dacrt5d --tracer "dacrt5d cull=cone" \
    --tracer "dacrt5d stop=fixed" --tracer "dacrt5d hand_over=1000" --tracer "dacrt5d space=major" \
    --tracer "dacrt5d spatial=false"
  # Sponza from inside (bench/common.py's preset camera and light), then the dragon (without
  # the first hybrid: its random rays take 83 s a call there).
  run "$S/sponza.obj.gz" --width 256 --random 65536 --bounces 3 --repeat 2 --threads 1 \
    --eye -13,2.5,0 --look 10,4.5,0 --fov 60 --light 0,12,0 \
    --tracer bvh --tracer dacrt --tracer dacrt5d --tracer "dacrt5d cull=cone" \
    --tracer "dacrt5d stop=fixed" --tracer "dacrt5d hand_over=1000" --tracer "dacrt5d space=major"
  run "$S/dragon_vrip.ply.gz" --width 256 --random 65536 --bounces 3 --repeat 2 --threads 1 \
    --tracer bvh --tracer dacrt --tracer dacrt5d --tracer "dacrt5d cull=cone" \
    --tracer "dacrt5d stop=fixed" --tracer "dacrt5d hand_over=1000"
  # Frustum against cone where every ray goes through its bundle's 5D recursion.
  for sc in bun_zipper.ply sponza.obj.gz dragon_vrip.ply.gz; do
    cam=()
    [ "$sc" = sponza.obj.gz ] && cam=(--eye -13,2.5,0 --look 10,4.5,0 --fov 60 --light 0,12,0)
    run "$S/$sc" --width 256 --random 65536 --bounces 3 --repeat 2 --threads 1 "${cam[@]}" \
      --tracer "dacrt5d hand_over=1000" --tracer "dacrt5d hand_over=1000 cull=cone"
  done
  # The cost stop's constants (the post's C_r, C_g; the author's 16/16 is the default).
  for sc in bun_zipper.ply sponza.obj.gz; do
    cam=()
    [ "$sc" = sponza.obj.gz ] && cam=(--eye -13,2.5,0 --look 10,4.5,0 --fov 60 --light 0,12,0)
    run "$S/$sc" --width 256 --random 65536 --bounces 3 --repeat 2 --threads 1 "${cam[@]}" \
      --tracer dacrt5d --tracer "dacrt5d c_r=4 c_g=4" --tracer "dacrt5d c_r=8 c_g=8" \
      --tracer "dacrt5d c_r=32 c_g=32" --tracer "dacrt5d c_r=64 c_g=64" \
      --tracer "dacrt5d c_r=4 c_g=32" --tracer "dacrt5d c_r=32 c_g=4" \
      --tracer "dacrt5d leaf_tris=8" --tracer "dacrt5d leaf_tris=128" \
      --tracer "dacrt5d shared_leaf=4" --tracer "dacrt5d shared_leaf=32"
  done
} | tee "$OUT"
