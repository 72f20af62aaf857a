#!/bin/bash
# BVH refit vs rebuild on animate --motion explode, alternating policies, 3 rounds.
cd /work/main
for round in 1 2 3; do
 for scene in dragon_vrip_res2.ply.gz bun_zipper.ply; do
  for fr in 8 32; do
   for u in rebuild refit auto; do
    if [ $u = refit ] && [ $fr = 8 ] && [ $scene = dragon_vrip_res2.ply.gz ]; then :; fi
    ./target/release/raysift animate ../shared/scenes/$scene --motion explode --frames $fr --tracer bvh --opt update=$u --threads 1 --pin --width 512 --height 512 --json --no-images --out /tmp/anim 2>/dev/null | python3 -c "
import json,sys; d=json.load(sys.stdin); print('$round $scene $fr $u', round(d['mean_prepare_ms'],1), round(d['mean_trace_ms'],1), round(d['mean_frame_ms'],1), flush=True)"
   done
  done
 done
done
