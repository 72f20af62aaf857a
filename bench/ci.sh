#!/usr/bin/env bash
# CI: unit tests of bench/common.py, then the agreement check: every raysift tracer against
# Embree 4.4 on one small scene (< 1 minute once built). Call from .ci/run:   bash bench/ci.sh
set -euo pipefail
cd "$(dirname "$0")/.."
python3 -m pip install -q -r bench/requirements.txt
python3 -m unittest discover -s bench -p 'test_*.py'
cargo build --release -q -p raysift-cli
cargo build --release -q --manifest-path bench/Cargo.toml
python3 bench/run.py --check --no-build
