#!/usr/bin/env bash
# Set up (idempotently) and run every check and test: lint, types, formatting, C++ and Python.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
export PATH="$PWD/.venv/bin:$PATH"

echo "== ruff";  ruff check host tests protocol firmware
echo "== mypy";  mypy
if compgen -G "firmware/**/*.[ch]pp" >/dev/null || [ -n "$(git ls-files '*.cpp' '*.hpp' '*.h' '*.c' 2>/dev/null)" ]; then
  echo "== clang-format"
  git ls-files '*.cpp' '*.hpp' '*.h' '*.c' | grep -v '^build/' | xargs -r clang-format --dry-run --Werror
fi
echo "== C++ build and ctest"
cmake -S . -B build/native -DCMAKE_BUILD_TYPE=Debug >/dev/null
cmake --build build/native -j"$(nproc)"
ctest --test-dir build/native --output-on-failure -j"$(nproc)"
echo "== pytest"
pytest -n "$(nproc)" -q "$@"
