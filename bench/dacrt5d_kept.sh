#!/usr/bin/env bash
# Issue #17, the bundles through the kept levels (BENCHMARKS.md § "dacrt5d: bundles through the
# kept levels"): every batch of dacrt5d_bench for bvh, dacrt, dacrt5d and three variants
# (bundles starting on every triangle; kept levels down to 256 triangles; kept levels split at
# the centroids' middle) in one process, contenders alternating, best of 3, one thread; then,
# with OLD=path/to/an/older/dacrt5d_bench, that binary's dacrt5d and this one's in alternating
# processes (two rounds each).
#   bash bench/dacrt5d_kept.sh [OUT.md]        (scenes from ../shared/scenes or RAYSIFT_SCENES)
set -euo pipefail
cd "$(dirname "$0")/.."
S=${RAYSIFT_SCENES:-../shared/scenes}
OUT=${1:-bench/results/$(date +%F)-dacrt5d-kept.md}
cargo build --release -q -p raysift --example dacrt5d_bench
B=./target/release/examples/dacrt5d_bench
cams() { [ "$1" = sponza.obj.gz ] && echo "--eye -13,2.5,0 --look 10,4.5,0 --fov 60 --light 0,12,0" || true; }
run() { local b=$1; shift; echo; echo '```text'; echo "dacrt5d_bench $*"; echo '```'; echo; "$b" "$@"; }
{
  echo "# dacrt5d: bundles through the kept levels, $(date -u '+%F %H:%M UTC'), $(git rev-parse --short HEAD)"
  for sc in bun_zipper.ply sponza.obj.gz dragon_vrip.ply.gz; do
    # shellcheck disable=SC2046
    run "$B" "$S/$sc" --width 512 --random 65536 --bounces 3 --repeat 3 --threads 1 $(cams $sc) \
      --tracer bvh --tracer dacrt --tracer dacrt5d --tracer "dacrt5d kept_bundles=false" \
      --tracer "dacrt5d top_leaf=256" --tracer "dacrt5d top_split=middle" --counters
  done
  if [ -n "${OLD:-}" ]; then
    echo; echo "## Against $OLD"
    for sc in bun_zipper.ply sponza.obj.gz dragon_vrip.ply.gz; do
      for round in 1 2; do
        for b in "$OLD" "$B"; do
          echo; echo "### $sc, round $round, $b"
          # shellcheck disable=SC2046
          run "$b" "$S/$sc" --width 512 --random 65536 --bounces 3 --repeat 3 --threads 1 \
            $(cams $sc) --tracer dacrt5d
        done
      done
    done
  fi
} | tee "$OUT"
