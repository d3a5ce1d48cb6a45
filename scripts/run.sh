#!/usr/bin/env bash
# Set up (idempotently) and run the main job. Until the virtual board lands, the main job is the
# accuracy benchmark of every estimator on the DESIGN.md scenarios.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
exec .venv/bin/jointangle bench accuracy "$@"
