"""Where the host finds what CMake built (the firmware replay library, the virtual devices, the
virtual boards, the AVR image).

One rule for every artefact: an environment variable naming the file wins; otherwise the
repository's build trees are searched, `build/native` first (the tree the README builds), then
the other `build/*/` trees by name; when asked to, the CMake target is built in `build/native`
(if that tree is configured) and the search repeated.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from collections.abc import Callable
from pathlib import Path

from jointangle.errors import InputError

REPO_ROOT = Path(__file__).resolve().parents[2]


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
    """The first file matching `root/build/*/<pattern>` (a glob): build/native first, then the
    other trees by name. `executable`: only files we may run."""
    hits = sorted(root.glob(f"build/*/{pattern}"),
                  key=lambda h: (h.parts[len(root.parts) + 1] != "native", str(h)))
    mode = os.X_OK if executable else os.R_OK
    return next((h for h in hits if h.is_file() and os.access(h, mode)), None)


def locate_built(pattern: str, *, env: str, target: str, missing: Callable[[str], InputError],
                 build: bool = False, root: Path = REPO_ROOT,
                 executable: bool = False) -> Path:
    """$env, else the build trees' `pattern` (search_build_trees), else — with `build` and a
    configured build/native — `cmake --build build/native --target <target>` and the search
    again. Otherwise raises missing(detail), detail saying where it looked or why building
    failed (" (looked under …)" / " and building it in … failed (…)")."""
    override = env_override(env)
    if override is not None:
        return override
    found = search_build_trees(pattern, root, executable=executable)
    if found is not None:
        return found
    tree = root / "build" / "native"
    if build and (tree / "CMakeCache.txt").is_file() and shutil.which("cmake"):
        res = subprocess.run(["cmake", "--build", str(tree), "--target", target],
                             capture_output=True, text=True, check=False)
        found = search_build_trees(pattern, root, executable=executable)
        if res.returncode == 0 and found is not None:
            return found
        tail = (res.stdout + res.stderr).strip().splitlines()[-1:] or [""]
        raise missing(f" and building it in {tree} failed ({tail[0][:160]})")
    raise missing(f" (looked under {root / 'build'})")


def find_built(filename: str, subdir: str, *, env: str, target: str, what: str,
               field: str) -> Path:
    """Path of `filename` built by CMake `target` into `<build tree>/<subdir>` (not built here).

    Raises InputError naming the target to build (and `env` to set) when it is not found.
    """
    return locate_built(
        f"{subdir}/{filename}", env=env, target=target,
        missing=lambda _: InputError(
            f"the {what} ({filename}) is not built: run `cmake -S . -B build/native && "
            f"cmake --build build/native --target {target}`, or set {env}", field=field))
