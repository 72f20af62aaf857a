#!/usr/bin/env bash
# The box gate's cost (issue #20): trace time before (c887de2: gate refuses t off the box, range
# test first) and after (ce9db61: gate moves t into the box interval, range test after it), one
# thread, alternating binaries, 3 rounds x (trace --repeat 3, median). BEFORE/AFTER: the two
# release `raysift` binaries.
set -euo pipefail
S=../shared/scenes
R=/tmp/gate
for round in 1 2 3; do
  for job in "dragon_vrip.ply.gz dragon-cam bvh" "dragon_vrip.ply.gz dragon-cam dacrt" \
             "dragon_vrip.ply.gz dragon-rand bvh" "dragon_vrip.ply.gz dragon-rand dacrt" \
             "sponza.obj.gz sponza-cam bvh" "sponza.obj.gz sponza-cam dacrt"; do
    set -- $job
    if [ $((round % 2)) -eq 1 ]; then order="BEFORE AFTER"; else order="AFTER BEFORE"; fi
    for who in $order; do
      bin=${!who}
      ms=$($bin trace $S/$1 --rays $R/$2.npy --tracer $3 --threads 1 --repeat 3 --json \
        | python3 -c 'import json,sys; j=json.load(sys.stdin); print(j["trace_ms"], j["hits"])')
      echo "$round $2 $3 $who $ms"
    done
  done
done
