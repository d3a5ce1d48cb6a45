#!/usr/bin/env bash
# Install everything jointangle needs, idempotently; fast when already installed.
#   - Debian packages: the AVR and Arm (Pico) toolchains, simavr, Eigen, clang (libFuzzer), tmux, ...
#   - a Python 3.11 virtual environment in .venv with the package and its dev extras.
#   - Node.js and the Pico virtual board's npm packages (rp2040js, koffi; pinned in
#     firmware/sim/pico_board/package-lock.json) in firmware/sim/pico_board/node_modules.
set -euo pipefail
cd "$(dirname "$0")/.."

APT_PACKAGES=(
  build-essential cmake pkg-config git python3-venv
  gcc-avr avr-libc binutils-avr avrdude arduino-core-avr arduino-mk arduino-builder
  simavr libsimavr-dev libelf-dev libeigen3-dev
  clang clang-format libclang-rt-14-dev valgrind tmux
  gcc-arm-none-eabi libnewlib-arm-none-eabi libstdc++-arm-none-eabi-newlib
)

# Node.js (>= 18) for sim://pico: Debian's nodejs and npm unless a node is installed already
# (a NodeSource node brings its own npm, which Debian's npm package would conflict with).
command -v node >/dev/null || APT_PACKAGES+=(nodejs npm)

missing=()
for p in "${APT_PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "setup: installing Debian packages: ${missing[*]}"
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

PYTHON="${PYTHON:-python3.11}"
command -v "$PYTHON" >/dev/null || PYTHON=python3
if [ ! -x .venv/bin/python ]; then
  echo "setup: creating .venv with $PYTHON"
  "$PYTHON" -m venv .venv
fi
stamp=".venv/.jointangle-installed"
want="$(sha256sum pyproject.toml | cut -d' ' -f1)"
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
  echo "setup: installing Python packages from pyproject.toml"
  .venv/bin/python -m pip install -q --upgrade pip
  .venv/bin/python -m pip install -q -e '.[dev]'
  echo "$want" > "$stamp"
fi
# The checkout's package as a plain path entry, as before the wheel's build backend: the
# editable finder scikit-build-core installs maps `jointangle` to this checkout even when
# PYTHONPATH names another (a git worktree tried with this .venv). docs/packaging.md.
site="$(.venv/bin/python -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
rm -f "$site/_editable_skbc_jointangle.pth"
[ "$(cat "$site/jointangle-checkout.pth" 2>/dev/null)" = "$PWD/host" ] \
  || echo "$PWD/host" > "$site/jointangle-checkout.pth"

# The Pico virtual board's packages, exactly as locked (no install scripts: koffi ships its
# prebuilt binaries); again only when the lock file changed.
pico_dir="firmware/sim/pico_board"
pico_stamp="$pico_dir/node_modules/.jointangle-installed"
pico_want="$(sha256sum "$pico_dir/package-lock.json" | cut -d' ' -f1)"
if [ ! -f "$pico_stamp" ] || [ "$(cat "$pico_stamp")" != "$pico_want" ]; then
  echo "setup: installing the Pico virtual board's npm packages"
  npm ci --prefix "$pico_dir" --ignore-scripts --no-audit --no-fund --loglevel=error
  echo "$pico_want" > "$pico_stamp"
fi
