#!/usr/bin/env bash
# Agreement check for CI: every raysift tracer against Embree 4.4 on one small scene (< 1 minute
# once built). Call from .ci/run:   bash bench/ci.sh
set -euo pipefail
cd "$(dirname "$0")/.."
python3 -m pip install -q -r bench/requirements.txt
cargo build --release -q -p raysift-cli
cargo build --release -q --manifest-path bench/Cargo.toml
python3 bench/run.py --check --no-build
