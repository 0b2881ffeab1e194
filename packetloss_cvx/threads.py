"""The BLAS thread policy: the library's own small dense linear algebra runs single-threaded.

The matrices here are small (n, m <= tens, N m <= 160 on the dense path), where a threaded BLAS
spends more time waking and synchronising threads than computing: on 2 cores the dense closed form at
N = 40 runs an order of magnitude slower on OpenBLAS's default threads than on one (docs/performance.md,
section 11). So every public entry point that computes
(`blas_limited`) runs with the BLAS thread pools limited to `blas_threads` threads
(default 1) through threadpoolctl, and restores them on return: the user's own setting, and NumPy
calls outside this library, are untouched.

Allow more with ``set_blas_threads(k)`` (``None``: leave BLAS alone), or the environment variable
``PACKETLOSS_CVX_BLAS_THREADS`` (an integer >= 1, or ``none``) read at import.
"""

from __future__ import annotations

import functools
import numbers
import os
import sys
import threading
from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np
from threadpoolctl import ThreadpoolController

from .errors import InputError

__all__ = ["BLAS_THREADS_ENV", "blas_limited", "blas_threads", "set_blas_threads"]

#: The environment variable that sets the policy at import: an integer >= 1, or "none".
BLAS_THREADS_ENV = "PACKETLOSS_CVX_BLAS_THREADS"

F = TypeVar("F", bound=Callable[..., Any])

_lock = threading.RLock()
_local = threading.local()
_state: dict[str, Any] = {"controller": None, "modules": 0, "threads": 1}


def _check(value: Any, field: str) -> int | None:
    if value is None:
        return None
    if isinstance(value, str):
        if value.strip().lower() == "none":
            return None
        try:
            value = int(value)
        except ValueError:
            raise InputError(field, f"expected an integer >= 1 or 'none', found {value!r}") from None
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral) or value < 1:
        raise InputError(field, f"expected an integer >= 1 or None, found {value!r}")
    return int(value)     # a NumPy integer too (e.g. from a grid of thread counts)


def set_blas_threads(threads: int | None) -> None:
    """Let the library's calls use at most ``threads`` BLAS threads (default 1); ``None`` leaves
    the BLAS thread pools as the process has them. O(1).

    Examples
    --------
    >>> set_blas_threads(2); blas_threads()
    2
    >>> set_blas_threads(1)
    """
    _state["threads"] = _check(threads, "threads")


def blas_threads() -> int | None:
    """The current limit (None: no limit). O(1).

    Examples
    --------
    >>> set_blas_threads(None); print(blas_threads())
    None
    >>> set_blas_threads(1); blas_threads()
    1
    """
    return _state["threads"]


def _controller() -> ThreadpoolController:
    """A controller of the BLAS libraries loaded now: scanning them is not free, so it is made again
    only when modules were imported since (an import may load another BLAS, e.g. cvxpy's)."""
    with _lock:
        if _state["controller"] is None or _state["modules"] != len(sys.modules):
            _state["controller"] = ThreadpoolController()
            _state["modules"] = len(sys.modules)
        return _state["controller"]


def blas_limited(fn: F) -> F:
    """Run ``fn`` with the BLAS pools limited to `blas_threads` threads, restored on return.

    Nested calls (a limited function calling another) limit once, at the outermost call of each
    thread: the inner ones cost a thread-local counter, only the outermost call threadpoolctl's switch. Across
    Python threads, threadpoolctl lets only one thread at a time own a shared (pthreads) OpenBLAS
    pool: calls from other threads then run with whatever that thread set, and nobody's restore
    overwrites another's.

    Examples
    --------
    >>> from threadpoolctl import threadpool_info
    >>> @blas_limited
    ... def pools():
    ...     return [p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"]
    >>> all(k == blas_threads() for k in pools())   # inside: every BLAS pool at the limit (1)
    True
    >>> pools.__name__                               # functools.wraps keeps the name
    'pools'
    """
    @functools.wraps(fn)
    def limited(*args: Any, **kwargs: Any) -> Any:
        threads = _state["threads"]
        if threads is None or getattr(_local, "depth", 0):
            return fn(*args, **kwargs)
        _local.depth = 1
        try:
            with _controller().limit(limits=threads, user_api="blas"):
                return fn(*args, **kwargs)
        finally:
            _local.depth = 0

    return limited  # type: ignore[return-value]


_state["threads"] = _check(os.environ.get(BLAS_THREADS_ENV, 1), BLAS_THREADS_ENV)
