#!/usr/bin/env bash
# The four-lane box gate (TriFromOrigin::box_gate4) against the refusing gate of c887de2: DACRT
# camera rays only (the path the gate cost), one thread, alternating binaries, 5 rounds x
# (trace --repeat 3, median). BEFORE/AFTER: the two release `raysift` binaries; rays as in
# 2026-12-02-gate.sh (`raysift rays camera ... --width 1024 --height 1024`).
set -euo pipefail
S=../shared/scenes
R=/tmp/gate
for round in 1 2 3 4 5; do
  for job in "dragon_vrip.ply.gz dragon-cam" "sponza.obj.gz sponza-cam"; do
    set -- $job
    if [ $((round % 2)) -eq 1 ]; then order="BEFORE AFTER"; else order="AFTER BEFORE"; fi
    for who in $order; do
      bin=${!who}
      ms=$($bin trace $S/$1 --rays $R/$2.npy --tracer dacrt --threads 1 --repeat 3 --json 2>/dev/null \
        | python3 -c 'import json,sys; j=json.load(sys.stdin); print(j["trace_ms"], j["hits"])')
      echo "$round $2 dacrt $who $ms"
    done
  done
done
