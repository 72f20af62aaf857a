#!/bin/sh
# Runs one fuzz target with the limits docs/fuzzing.md records, from the repository root or fuzz/:
#
#     fuzz/run.sh TARGET [RUNS] [extra libFuzzer flags...]
#
# TARGET is obj, ply, off, gltf, gzip or npy; RUNS defaults to 1000000 executions. The working
# corpus fuzz/corpus-work/TARGET (not committed) starts from the committed fuzz/corpus/TARGET
# and the seeds of fuzz/make_seeds.py; crashes go to fuzz/artifacts/TARGET/. Needs the nightly
# toolchain and cargo-fuzz (`cargo install cargo-fuzz`). Runs under `nice -n 10`.
set -eu
cd "$(dirname "$0")"
t=${1:?usage: fuzz/run.sh TARGET [RUNS] [libFuzzer flags...]}
runs=${2:-1000000}
[ $# -ge 2 ] && shift 2 || shift 1
mkdir -p "corpus-work/$t" "corpus/$t"
[ -d "seeds/$t" ] || python3 make_seeds.py
cp -n "corpus/$t"/* "seeds/$t"/* "corpus-work/$t"/ 2>/dev/null || true
dict=""
[ -f "dict/$t.dict" ] && dict="-dict=dict/$t.dict"
# -a: debug assertions and overflow checks on, as in the test profile.
# -rss_limit_mb: the whole process (ASan's quarantine and libFuzzer's corpus included).
# -malloc_limit_mb: any single allocation above 64 MB is reported as a crash; inputs are at
#  most 16 KB (-max_len), so no reader may need anything near that.
# -timeout: an input running longer than 10 s is reported as a hang.
exec nice -n 10 cargo +nightly fuzz run -a -O "$t" "corpus-work/$t" -- \
    -runs="$runs" -max_len=16384 -rss_limit_mb=1024 -malloc_limit_mb=64 -timeout=10 \
    -print_final_stats=1 $dict "$@"
