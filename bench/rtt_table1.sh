#!/bin/sh
# The relevant-triangle shafts paper's Table 1 at 640x480 (primary and point-light shadow rays,
# rtt against the single-ray kdtree, alternating, best of 3, one thread) on the bench's cameras
# (BENCHMARKS.md § Scenes and cameras). Usage (from the repository root):
#   cargo build --release -p raysift --example rtt_bench
#   sh bench/rtt_table1.sh [THREADS] [AA] [KD_PACKETS] > table1.txt
set -e
T=${1:-1}; AA=${2:-1}; KP=${3:-1}
BIN=${CARGO_TARGET_DIR:-target}/release/examples/rtt_bench
S=../shared/scenes
run() { $BIN "$@" --threads "$T" --repeat 3 --aa "$AA" --kd-packets "$KP"; }
run $S/CornellBox-Original.obj --eye -0.01,0.995,3.48 --look -0.01,0.995,-0.025 --fov 45 --light 0,1.9,0.3
run $S/bun_zipper.ply --eye -0.0168,0.11,0.251 --look -0.0168,0.11,-0.00154 --fov 27 --light 0.0766,0.342,0.143
run $S/dragon_vrip.ply.gz --eye -0.00588,0.125,0.293 --look -0.00588,0.125,-0.0046 --fov 27 --light 0.117,0.342,0.105
run $S/sponza.obj.gz --eye -13,2.5,0 --look 10,4.5,0 --fov 60 --light 0,12,0
run soup:100000 --eye 2.74e-05,5.4e-05,3.61 --look 2.74e-05,5.4e-05,0.000153 --fov 45 --light 1.25,3.13,2.5
