"""Where the host finds what CMake built (the firmware replay library, the virtual devices).

One rule for every artefact: an environment variable naming the file wins; otherwise the
repository's build trees are searched, `build/native` first.
"""

from __future__ import annotations

import os
from pathlib import Path

from jointangle.errors import InputError

REPO_ROOT = Path(__file__).resolve().parents[2]


def find_built(filename: str, subdir: str, *, env: str, target: str, what: str,
               field: str) -> Path:
    """Path of `filename` built by CMake `target` into `<build tree>/<subdir>`.

    Raises InputError naming the target to build (and `env` to set) when it is not found.
    """
    override = os.environ.get(env)
    if override:
        path = Path(override)
        if not path.is_file():
            raise InputError(f"{env}={override} does not exist", field=env)
        return path
    build = REPO_ROOT / "build"
    for candidate in (build / "native" / subdir / filename,
                      *sorted(build.glob(f"*/{subdir}/{filename}"))):
        if candidate.is_file():
            return candidate
    raise InputError(f"the {what} ({filename}) is not built: run `cmake -S . -B build/native && "
                     f"cmake --build build/native --target {target}`, or set {env}", field=field)
