"""Reading an input file safely: only regular files, only up to a size cap, checked before a
byte is read (`--rig /dev/urandom` read forever; a FIFO blocks). Errors are InputErrors naming
the file, one line each."""

from __future__ import annotations

import os
import stat
from pathlib import Path

from jointangle.errors import InputError

RIG_MAX_BYTES = 1 << 20  # 1 MiB: a rig file is ~1 kB
CSV_MAX_BYTES = 2 << 30  # 2 GiB: an hour at 1 kHz of 8 sensors with gyro and truth is ~1.2 GB

_KINDS = ((stat.S_ISDIR, "a folder"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
          (stat.S_ISSOCK, "a socket"))


def read_input_bytes(path: str | Path, what: str, max_bytes: int) -> bytes:
    """The bytes of a regular file of at most `max_bytes`; anything else refused before
    reading ("what" names the kind of file in the message, e.g. "rig file")."""
    p = Path(path)
    try:
        st = os.stat(p)  # follows a symlink: the file it names is what is read
    except OSError as exc:
        raise InputError(f"cannot read {what}: {exc.strerror}", path=p) from None
    if not stat.S_ISREG(st.st_mode):
        kind = next((name for test, name in _KINDS if test(st.st_mode)), "not a regular file")
        raise InputError(f"is {kind}, not a regular file: expected a {what}", path=p)
    if st.st_size > max_bytes:
        raise InputError(f"{st.st_size} bytes, over the {_size(max_bytes)} a {what} may have "
                         "(is this the right file?)", path=p)
    try:
        with open(p, "rb") as f:
            data = f.read(max_bytes + 1)  # bounded even if it grows meanwhile
    except OSError as exc:
        raise InputError(f"cannot read {what}: {exc.strerror}", path=p) from None
    if len(data) > max_bytes:
        raise InputError(f"over the {_size(max_bytes)} a {what} may have (it grew while "
                         "being read)", path=p)
    return data


def read_input_text(path: str | Path, what: str, max_bytes: int, expected: str) -> str:
    """`read_input_bytes` decoded as UTF-8 (the offset of a bad byte named; `expected` says
    what text was expected, e.g. "a rig file is TOML")."""
    data = read_input_bytes(path, what, max_bytes)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"not UTF-8 text (byte {exc.start}): {expected}", path=path) from None


def _size(n: int) -> str:
    for unit, scale in (("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)):
        if n >= scale:
            return f"{n / scale:g} {unit}"
    return f"{n} bytes"
