#!/usr/bin/env bash
# Two raysift binaries on the same rays files, alternating (A B A B ...), pinned, one process per
# run, each `--repeat 3` (its median counts); prints one line per run and then, per case, the
# medians over rounds and the ratio B / A of the frame (prepare + trace).
#
#   bench/ab.sh A_BINARY B_BINARY ROUNDS "SCENE RAYS.npy THREADS [--opt k=v ...]" ...
#
# Example (issue #21, BENCHMARKS.md § DACRT: random and bounce rays):
#   bench/ab.sh /work/target-base/release/raysift target/release/raysift 3 \
#     "../shared/scenes/dragon_vrip.ply.gz /tmp/drand.npy 1" "../shared/scenes/sponza.obj.gz /tmp/srand.npy 2"
set -euo pipefail
a=$1 b=$2 rounds=$3
shift 3
out=$(mktemp)
for round in $(seq "$rounds"); do
  for case in "$@"; do
    read -r scene rays threads opts <<<"$case"
    for side in A B; do
      bin=$a
      [ "$side" = B ] && bin=$b
      # shellcheck disable=SC2086
      "$bin" trace "$scene" --rays "$rays" --tracer dacrt --threads "$threads" --pin --repeat 3 \
        --json $opts 2>/dev/null | python3 -c "
import json, sys
j = json.load(sys.stdin)
print('$round', '$side', '$(basename "$rays")', '$threads', j['prepare_ms'], j['trace_ms'])" | tee -a "$out"
    done
  done
done
python3 - "$out" <<'PY'
import collections, statistics as st, sys
d = collections.defaultdict(list)
for line in open(sys.argv[1]):
    _, side, rays, th, p, t = line.split()
    d[(rays, th, side)].append((float(p), float(t)))
for rays, th in sorted({(r, t) for r, t, _ in d}):
    med = {s: [st.median(x) for x in zip(*d[(rays, th, s)])] for s in "AB"}
    fa, fb = sum(med["A"]), sum(med["B"])
    print(f"{rays} {th}t  A prepare {med['A'][0]:.1f} trace {med['A'][1]:.1f} frame {fa:.1f}  |  "
          f"B prepare {med['B'][0]:.1f} trace {med['B'][1]:.1f} frame {fb:.1f}  |  B/A {fb / fa:.3f}")
PY
rm -f "$out"
