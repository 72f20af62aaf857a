#!/bin/sh
# kd-tree against the BVH on the ../shared/scenes meshes, one thread, the two tracers alternating
# per scene (same process binary, same rays): build time, bytes per triangle, camera and random
# rays (closest hit) and random rays (occlusion). Usage (from the repository root):
#   cargo build --release -p raysift --example trace_bench
#   sh bench/kdtree_vs_bvh.sh [WIDTH] [RANDOM] [THREADS] [REPEAT] > kd.txt
set -e
W=${1:-512}; R=${2:-262144}; T=${3:-1}
BIN=target/release/examples/trace_bench
S=../shared/scenes
for scene in cornell $S/bun_zipper.ply $S/sponza.obj.gz $S/dragon_vrip.ply.gz; do
  for round in 1 2; do
    for tracer in kdtree bvh; do
      echo "## round $round"
      $BIN "$scene" $tracer --threads "$T" --width "$W" --random "$R" --repeat "${4:-3}"
    done
  done
done
