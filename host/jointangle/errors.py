"""Errors raised for bad external input.

Every message names what is wrong and where (file, line, field), so the command line can print
it as is and exit with status 2.
"""

from __future__ import annotations

from pathlib import Path


class InputError(Exception):
    """Bad external input: a rig file, a CSV, a recording or a command-line value."""

    def __init__(
        self,
        message: str,
        *,
        path: str | Path | None = None,
        line: int | None = None,
        field: str | None = None,
    ) -> None:
        self.path = None if path is None else str(path)
        self.line = line
        self.field = field
        self.reason = message
        super().__init__(self._format())

    def _format(self) -> str:
        where = []
        if self.path is not None:
            where.append(self.path)
        if self.line is not None:
            where.append(f"line {self.line}")
        if self.field is not None:
            where.append(f"field '{self.field}'")
        prefix = ", ".join(where)
        return f"{prefix}: {self.reason}" if prefix else self.reason


class GeometryError(InputError):
    """A sensor array whose geometry cannot support the model (e.g. coincident sensors)."""
