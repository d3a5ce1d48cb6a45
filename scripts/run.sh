#!/usr/bin/env bash
# Set up (idempotently) and run the main job. Until the virtual board lands, the main job is the
# accuracy benchmark of every estimator on the DESIGN.md scenarios.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
# The `firmware` estimator replays the fixed-point core through a small C library.
cmake -S . -B build/native -DCMAKE_BUILD_TYPE=Debug >/dev/null
cmake --build build/native --target ja_filter_replay -j"$(nproc)" >/dev/null
exec .venv/bin/jointangle bench accuracy "$@"
