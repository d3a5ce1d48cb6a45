"""Where the host finds its compiled parts (the firmware replay library, the virtual devices, the
virtual boards, the AVR image).

One rule for every artefact:

1. an environment variable naming the file wins;
2. the installed package's own copies in `jointangle/_built/` (a wheel puts them there,
   docs/packaging.md);
3. the repository's build trees, `build/native` first (the tree the README builds), then the
   other `build/*/` trees by name; when asked to, the CMake target is built in `build/native`
   (if that tree is configured) and the search repeated.

`$JOINTANGLE_HIDE_BUILT=1` hides 2 and 3 (a pure-Python installation, for the tests and for
`doctor`); the environment variables still win. A part that is not found is reported in one
line naming it and how to get it (`how_to_get`): in a checkout the CMake command, in an
installation the wheel or the sdist.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from jointangle.errors import InputError

REPO_ROOT = Path(__file__).resolve().parents[2]
PACKAGE_BUILT = Path(__file__).resolve().parent / "_built"
HIDE_ENV = "JOINTANGLE_HIDE_BUILT"


@dataclass(frozen=True)
class Part:
    """A compiled part the host can load or start."""

    what: str  # "the firmware replay library"
    pattern: str  # glob under a build tree: "firmware/libja_filter_replay.so"
    target: str  # its CMake target
    env: str  # the variable that names it directly
    needed_by: str  # the commands that need it
    executable: bool = False
    in_wheel: bool = True  # the wheel carries it (the AVR parts need avr-gcc and simavr)

    @property
    def filename(self) -> str:
        return Path(self.pattern).name


# Every compiled part, in the order `doctor` reports them. The rows are the single place the
# file names, targets and variables are written (estimators/mirror.py, boards/sim_devices.py,
# boards/launchers.py and cli/flash.py look theirs up here).
FILTER_REPLAY = Part("the firmware replay library", "firmware/libja_filter_replay.so",
                     "ja_filter_replay", "JOINTANGLE_FIRMWARE_LIB",
                     "estimate/plot --filter firmware, replay --verify-firmware, bench parity")
SIM_DEVICES = Part("the virtual device library", "firmware/sim/libja_sim_devices.so",
                   "ja_sim_devices", "JOINTANGLE_SIMDEV_LIB",
                   "live --i2c sim, the virtual I2C bus in Python")
NATIVE_BOARD = Part("the native virtual board", "firmware/**/ja_native_board", "ja_native_board",
                    "JOINTANGLE_NATIVE_BOARD", "--port sim://native", executable=True)
AVR_BOARD = Part("the AVR virtual board", "firmware/sim/ja_avr_board", "ja_avr_board",
                 "JOINTANGLE_AVR_BOARD", "--port sim://avr", executable=True, in_wheel=False)
AVR_IMAGE = Part("the AVR image jointangle_mega2560.elf", "avr/jointangle_mega2560.elf",
                 "avr_images", "JOINTANGLE_AVR_IMAGE", "--port sim://avr, flash",
                 in_wheel=False)
PICO_BOARD_LIB = Part("the virtual boards' C library", "firmware/sim/libja_sim_board.so",
                      "ja_sim_board", "JOINTANGLE_SIM_BOARD_LIB", "--port sim://pico",
                      in_wheel=False)
PICO_BOOTROM = Part("the Pico emulator's bootrom", "firmware/sim/pico_bootrom.bin",
                    "ja_pico_bootrom", "JOINTANGLE_PICO_BOOTROM", "--port sim://pico",
                    in_wheel=False)
PICO_IMAGE = Part("the Pico image jointangle_pico.elf", "pico/jointangle_pico.elf", "pico_images",
                  "JOINTANGLE_PICO_IMAGE", "--port sim://pico, flash --board pico",
                  in_wheel=False)
PARTS: tuple[Part, ...] = (FILTER_REPLAY, SIM_DEVICES, NATIVE_BOARD, AVR_BOARD, AVR_IMAGE,
                           PICO_BOARD_LIB, PICO_BOOTROM, PICO_IMAGE)


def hidden() -> bool:
    """$JOINTANGLE_HIDE_BUILT set: only the environment variables find compiled parts."""
    return os.environ.get(HIDE_ENV, "") not in ("", "0")


def in_checkout(root: Path = REPO_ROOT) -> bool:
    """Whether the package runs from the repository (an editable install), not a wheel."""
    return (root / "CMakeLists.txt").is_file() and (root / "firmware").is_dir()


def how_to_get(target: str, env: str, root: Path = REPO_ROOT) -> str:
    """How to get a missing part, for a one-line error: the CMake command in a checkout; in an
    installation, a wheel built for this platform or the sdist (which compiles the parts)."""
    cmake = f"`cmake -S . -B build/native && cmake --build build/native --target {target}`"
    if in_checkout(root):
        return f"build it with {cmake}, or set {env}"
    if any(p.target == target and not p.in_wheel for p in PARTS):
        return (f"no wheel carries it (it needs avr-gcc and simavr): build it in a checkout of "
                f"the repository (`bash scripts/setup.sh`, then {cmake}), or set {env}")
    return ("install a jointangle wheel built for this platform, or build one from the sdist "
            f"(`pip install --no-binary jointangle jointangle`: CMake, a C++17 compiler and "
            f"Eigen), or set {env}")


def env_override(env: str) -> Path | None:
    """The file $env names (None when unset); an InputError naming `env` if it does not exist."""
    value = os.environ.get(env)
    if not value:
        return None
    if not Path(value).is_file():
        raise InputError(f"{env}={value} does not exist", field=env)
    return Path(value)


def search_build_trees(pattern: str, root: Path = REPO_ROOT, *,
                       executable: bool = False) -> Path | None:
    """The installed package's copy of the file (`_built/<name>`), else the first file matching
    `root/build/*/<pattern>` (a glob): build/native first, then the other trees by name.
    `executable`: only files we may run. Nothing while $JOINTANGLE_HIDE_BUILT is set."""
    if hidden():
        return None
    mode = os.X_OK if executable else os.R_OK
    packaged = PACKAGE_BUILT / Path(pattern).name
    if packaged.is_file() and os.access(packaged, mode):
        return packaged
    hits = sorted(root.glob(f"build/*/{pattern}"),
                  key=lambda h: (h.parts[len(root.parts) + 1] != "native", str(h)))
    return next((h for h in hits if h.is_file() and os.access(h, mode)), None)


def locate_built(pattern: str, *, env: str, target: str, missing: Callable[[str], InputError],
                 build: bool = False, root: Path = REPO_ROOT,
                 executable: bool = False) -> Path:
    """$env, else the package's copy or the build trees' `pattern` (search_build_trees), else —
    with `build` and a configured build/native — `cmake --build build/native --target <target>`
    and the search again. Otherwise raises missing(detail), detail saying where it looked or why
    building failed (" (looked under …)" / " and building it in … failed (…)")."""
    override = env_override(env)
    if override is not None:
        return override
    found = search_build_trees(pattern, root, executable=executable)
    if found is not None:
        return found
    tree = root / "build" / "native"
    if build and not hidden() and (tree / "CMakeCache.txt").is_file() and shutil.which("cmake"):
        res = subprocess.run(["cmake", "--build", str(tree), "--target", target],
                             capture_output=True, text=True, check=False)
        found = search_build_trees(pattern, root, executable=executable)
        if res.returncode == 0 and found is not None:
            return found
        tail = (res.stdout + res.stderr).strip().splitlines()[-1:] or [""]
        raise missing(f" and building it in {tree} failed ({tail[0][:160]})")
    if hidden():
        raise missing(f" (hidden by {HIDE_ENV})")
    if not in_checkout(root):
        raise missing(" in this installation")
    raise missing(f" (looked under {root / 'build'})")


def find_part(part: Part, *, build: bool = False, field: str | None = None,
              root: Path = REPO_ROOT) -> Path:
    """Path of a compiled part; an InputError in one line naming it, what needs it and how to
    get it (`how_to_get`) when it is not found."""
    return locate_built(
        part.pattern, env=part.env, target=part.target, build=build, root=root,
        executable=part.executable,
        missing=lambda detail: InputError(
            f"{part.what} ({part.filename}, for {part.needed_by}) is not built{detail}: "
            f"{how_to_get(part.target, part.env, root)}", field=field or part.env))


def find_built(filename: str, subdir: str, *, env: str, target: str, what: str,
               field: str) -> Path:
    """Path of `filename` built by CMake `target` into `<build tree>/<subdir>` (not built here).

    Raises InputError naming the target to build (and `env` to set) when it is not found.
    """
    return locate_built(
        f"{subdir}/{filename}", env=env, target=target,
        missing=lambda detail: InputError(
            f"the {what} ({filename}) is not built{detail}: {how_to_get(target, env)}",
            field=field))
