#!/usr/bin/env bash
# Set up (idempotently) and run the main job: the live readout of the joint angle, from the
# attached board, or from the native virtual board (the firmware compiled for x86, its virtual
# sensors playing a simulated movement) when none is attached. Extra arguments go to
# `jointangle live` (e.g. --port /dev/ttyACM0, --scenario gravity-impulse, --json-lines).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cmake -S . -B build/native -DCMAKE_BUILD_TYPE=Debug >/dev/null
cmake --build build/native --target ja_native_board ja_filter_replay -j"$(nproc)" >/dev/null
exec .venv/bin/jointangle live "$@"
