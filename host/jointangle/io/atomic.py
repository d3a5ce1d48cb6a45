"""Outputs written whole or not at all.

`atomic_path` hands the writer a temporary file beside the output and moves it into place
(`os.replace`) only once it is complete, so a failure mid-write (disk full, a kill) leaves the
file that was there before untouched and no half-written output. Write errors become an
`InputError` naming the output. `check_output_paths` lets a command with several outputs refuse
an output it cannot write before it writes any of them.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import stat
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path

from jointangle.errors import InputError


def _write_error(path: str | Path, exc: OSError, option: str | None = None) -> InputError:
    return InputError(f"cannot write: {exc.strerror or exc}", path=path, field=option)


def _is_special(path: Path) -> bool:
    """An existing non-regular file (/dev/null, a FIFO): written in place, it cannot be
    replaced."""
    try:
        mode = path.stat().st_mode
    except OSError:
        return False
    return not stat.S_ISREG(mode) and not stat.S_ISDIR(mode)


def _new_temp(target: Path) -> Path:
    """A new empty file beside `target`, created with the mode a new output would get (the
    umask applies) or, if `target` exists, with its permission bits."""
    for _ in range(100):
        tmp = target.with_name(f".{target.name}.{secrets.token_hex(4)}.tmp")
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        except FileExistsError:
            continue
        try:
            with contextlib.suppress(FileNotFoundError):
                os.fchmod(fd, stat.S_IMODE(target.stat().st_mode))
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise
        finally:
            os.close(fd)
        return tmp
    raise FileExistsError(f"no free temporary name beside {target}")  # pragma: no cover


def _sync(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield the path the caller writes the output to; on success it becomes `path`.

    A symlink is written through (its target is replaced). An existing special file
    (/dev/null, /dev/stdout, a FIFO) is written in place. An OSError while writing or
    replacing becomes an InputError naming `path`; the temporary file is removed.
    """
    out = Path(path)
    if _is_special(out):  # before resolving: /dev/stdout on a pipe resolves to no path
        try:
            yield out
        except BrokenPipeError:
            raise  # `--out /dev/stdout | head`: the command line stops quietly
        except OSError as exc:
            raise _write_error(out, exc) from None
        return
    target = Path(os.path.realpath(out))
    if target.is_dir():
        raise InputError("cannot write: is a folder", path=out)
    if target.exists() and not os.access(target, os.W_OK):
        raise InputError("cannot write: the file is read-only", path=out)
    try:
        tmp = _new_temp(target)
    except OSError as exc:
        raise _write_error(out, exc) from None
    try:
        yield tmp
        _sync(tmp)
        os.replace(tmp, target)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise _write_error(out, exc) from None
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def check_output_paths(outputs: Mapping[str, str | Path | None]) -> None:
    """Refuse, before anything is written, an output ({option: path}, None for an option not
    given) whose folder does not exist or is not writable, or that is itself a folder."""
    for option, path in outputs.items():
        if path is None:
            continue
        out = Path(path)
        if _is_special(out):
            continue
        target = Path(os.path.realpath(out))
        if target.is_dir():
            raise InputError("cannot write: is a folder", path=out, field=option)
        folder = target.parent
        if not folder.exists():
            raise InputError(f"cannot write: folder {folder} does not exist", path=out,
                             field=option)
        if not folder.is_dir():
            raise InputError(f"cannot write: {folder} is not a folder", path=out, field=option)
        if not os.access(folder, os.W_OK | os.X_OK):
            raise InputError(f"cannot write: no permission to create files in {folder}",
                             path=out, field=option)
