"""Progress of long library calls, shown on a terminal.

Library code says what it is doing with :func:`task` (a stage, with a count when it has
one) and the callable it yields (one step done). Both do nothing unless a display is open
(:func:`display`): the CLI opens one only when stderr is a terminal and the output is not
JSON, so scripts, tests, pipes and ``--json`` see no progress at all. The display is
``rich``'s, transient: it disappears when the command ends, leaving the command's own lines.
"""

from __future__ import annotations

import contextlib
import contextvars
import sys
from collections.abc import Callable, Iterator

__all__ = ["display", "task", "wanted"]

_BAR = contextvars.ContextVar("tcamlab_progress", default=None)


def _nothing(n: int = 1, description: str | None = None) -> None:
    """The step callable when no display is open."""


def wanted(json_output: bool = False, stream=None) -> bool:
    """Whether a command should show progress: its stream (stderr) is a terminal, no JSON."""
    stream = sys.stderr if stream is None else stream
    return not json_output and bool(getattr(stream, "isatty", lambda: False)())


@contextlib.contextmanager
def display(enabled: bool) -> Iterator[None]:
    """Show the :func:`task` stages opened inside this block as bars on stderr, if ``enabled``."""
    if not enabled or _BAR.get() is not None:
        yield
        return
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        SpinnerColumn,
        TextColumn,
        TimeElapsedColumn,
    )

    columns = (
        SpinnerColumn(),
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
    )
    with Progress(*columns, console=Console(stderr=True), transient=True) as bar:
        token = _BAR.set(bar)
        try:
            yield
        finally:
            _BAR.reset(token)


@contextlib.contextmanager
def task(description: str, total: int | None = None) -> Iterator[Callable[..., None]]:
    """One stage of a command ("fitting candidate effects", 12 steps).

    Yields ``step(n=1, description=None)``: ``n`` steps done, and the stage's new
    description if given (what it does next). Without an open :func:`display` it costs
    one context-variable lookup.
    """
    bar = _BAR.get()
    if bar is None:
        yield _nothing
        return
    tid = bar.add_task(description, total=total)
    try:
        yield lambda n=1, description=None: bar.update(tid, advance=n, description=description)
    finally:
        bar.remove_task(tid)
