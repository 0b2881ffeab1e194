"""Progress bars for long work: tqdm on stderr, off when stderr is not a terminal or when asked.

Every long API call takes ``progress: bool | None = None``: ``True`` shows a bar, ``False``
hides it, ``None`` (the default) shows it only when stderr is a terminal. The command line
passes ``False`` with ``--quiet``.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterable, Iterator
from typing import Any, TypeVar

__all__ = ["ESTIMATE_AFTER", "Bar", "label", "progress_bar", "terminal_columns", "wants_progress"]

#: Work estimated to take longer than this (seconds) has its estimate in the bar's label from the start
#: (tqdm's own remaining time appears only once the first step is done, which may be minutes away).
ESTIMATE_AFTER = 60.0

T = TypeVar("T")


def wants_progress(progress: bool | None) -> bool:
    """``progress`` resolved: ``None`` means "when stderr is a terminal".

    This is tqdm's own ``disable=None`` rule, decided here before tqdm is imported: handing ``None`` to tqdm
    would import it (tqdm.auto, a noticeable share of a short command's start-up) on every run that shows no
    bar, a piped or scripted command included.

    Examples
    --------
    >>> wants_progress(True), wants_progress(False)
    (True, False)
    """
    if progress is None:
        isatty = getattr(sys.stderr, "isatty", None)
        return bool(isatty and isatty())
    return bool(progress)


class Bar:
    """A no-op stand-in for a tqdm bar (the same ``update``/``close``/iteration interface).

    Examples
    --------
    >>> with Bar(range(3)) as bar:
    ...     total = sum(bar)
    ...     bar.update(3)
    ...     bar.set_postfix_str("done")
    >>> total, bar.close()                 # every call is accepted and shows nothing
    (3, None)
    """

    def __init__(self, iterable: Iterable[Any] | None = None) -> None:
        self.iterable = iterable

    def __iter__(self) -> Iterator[Any]:
        return iter(self.iterable if self.iterable is not None else ())

    def update(self, n: int = 1) -> None:
        """Nothing to show."""

    def set_postfix_str(self, text: str) -> None:
        """Nothing to show."""

    def close(self) -> None:
        """Nothing to close."""

    def __enter__(self) -> Bar:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def label(desc: str, estimate: float | None) -> str:
    """A bar's label with the estimated time of the whole work when it exceeds `ESTIMATE_AFTER`.

    Examples
    --------
    >>> label("sweep", 30.0), label("sweep", 754.0), label("simulate", 7200.0), label("audit", None)
    ('sweep', 'sweep (estimated 13 min)', 'simulate (estimated 2 h)', 'audit')
    """
    if estimate is None or not estimate > ESTIMATE_AFTER:
        return desc
    shown = f"{estimate / 3600:.2g} h" if estimate >= 5400 else f"{estimate / 60:.0f} min"
    return f"{desc} (estimated {shown})"


def progress_bar(iterable: Iterable[T] | None = None, *, total: int | None = None, desc: str = "",
                 progress: bool | None = None, estimate: float | None = None) -> Any:
    """A tqdm bar on stderr when `wants_progress` says so, else a silent `Bar`; ``estimate``
    (seconds, from budgets.estimated_seconds) is shown in its label when the work takes minutes (`label`).

    >>> list(progress_bar(range(3), progress=False))
    [0, 1, 2]
    """
    if not wants_progress(progress):
        return Bar(iterable)
    from tqdm.auto import tqdm  # lazy: tqdm is only needed when a bar is shown

    # a terminal that reports no size (a pty without a window size) would hide every bar: 80 x 24 then
    width = {"dynamic_ncols": True} if terminal_columns() else {"ncols": 80, "nrows": 24}
    return tqdm(iterable, total=total, desc=label(desc, estimate), file=sys.stderr, leave=False, **width)


def terminal_columns() -> int:
    """The width of the terminal stderr writes to, 0 when it reports none (or stderr is not a terminal). O(1).

    >>> isinstance(terminal_columns(), int)
    True
    """
    try:
        return os.get_terminal_size(sys.stderr.fileno()).columns
    except (OSError, ValueError, AttributeError):
        return 0
