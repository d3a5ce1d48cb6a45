"""Pieces the subcommands share: comma-separated name options and the progress bar of the
benchmarks that run every (scenario, estimator) pair."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from jointangle.errors import InputError


def parse_names(value: str | None, known: list[str], option: str) -> list[str] | None:
    """Names from a comma-separated option, each checked against `known`; None when empty."""
    if not value:
        return None
    names = [v.strip() for v in value.split(",") if v.strip()]
    for n in names:
        if n not in known:
            raise InputError(f"unknown name {n!r}; known: {', '.join(known)}", field=option)
    return names


@contextmanager
def pair_progress(description: str, total: int) -> Iterator[Callable[[str, str], None]]:
    """A progress bar on stderr (only on a terminal) over `total` (scenario, name) tasks;
    yields the callback that marks one done."""
    err = Console(stderr=True)
    with Progress(TextColumn("[progress.description]{task.description}"), BarColumn(),
                  MofNCompleteColumn(), TimeElapsedColumn(), console=err, transient=True,
                  disable=not err.is_terminal) as progress:
        task = progress.add_task(description, total=total)

        def tick(scenario: str, name: str) -> None:
            progress.update(task, advance=1, description=f"{scenario} {name}")

        yield tick
