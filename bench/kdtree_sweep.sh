#!/bin/sh
# The kd-tree on every ../shared/scenes mesh: build time, bytes per triangle, camera and random
# rays, as single rays and as 4-ray packets, against the BVH, with 1 and 2 threads (trace_bench;
# the three contenders alternate per scene and thread count). Usage (from the repository root):
#   cargo build --release -p raysift --example trace_bench
#   sh bench/kdtree_sweep.sh [WIDTH] [RANDOM] [REPEAT] > sweep.txt
set -e
W=${1:-512}; R=${2:-131072}; K=${3:-2}
BIN=${CARGO_TARGET_DIR:-target}/release/examples/trace_bench
for scene in ../shared/scenes/*.ply ../shared/scenes/*.ply.gz ../shared/scenes/*.obj ../shared/scenes/*.obj.gz ../shared/scenes/*.off; do
  for T in 1 2; do
    $BIN "$scene" kdtree --threads "$T" --width "$W" --random "$R" --repeat "$K"
    $BIN "$scene" kdtree packets=4 --threads "$T" --width "$W" --random "$R" --repeat "$K"
    $BIN "$scene" bvh --threads "$T" --width "$W" --random "$R" --repeat "$K"
  done
done
