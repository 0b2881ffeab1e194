"""The text output of every subcommand, in one style: a heading, then aligned ``label  value``
lines, matrices with labelled rows and columns under their label, numbers in ``%.6g``.

Numbers appear in the same order as in the JSON (eigenvalues sorted by descending modulus,
as :func:`packetloss_cvx.results.eigenvalue_pairs` sorts them); a real eigenvalue prints as a
real number. Nothing here computes: each helper formats what it is given. O(size of the output).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..display import supported, supported_digits
from ..printable import printable
from ..results import eigenvalue_pairs

__all__ = ["INDENT", "LABEL_WIDTH", "MAX_COLUMNS", "MAX_ROWS", "eigenvalues", "fields", "labels", "matrix", "name",
           "num", "num_within", "numbers", "supported", "supported_digits", "table"]

INDENT = "  "
#: the width of the label column of :func:`fields`
LABEL_WIDTH = 16
#: the most rows and columns :func:`matrix` prints (the JSON has all of them)
MAX_ROWS = 20
MAX_COLUMNS = 8


def name(text: Any) -> str:
    r"""A user-given name or path as the text shows it: control characters escaped (:func:`~packetloss_cvx.
    printable.printable`), so a system named ``"\x1b[31m..."`` prints as ``\x1b[31m...``. O(len(text)).

    Examples
    --------
    >>> print(name("two\nlines\x07"))
    two\nlines\x07
    """
    return printable(str(text))


def num(value: Any, digits: int = 6) -> str:
    """One number, ``%.{digits}g``; None as ``-``.

    Examples
    --------
    >>> num(12.3456789), num(1e-12), num(None), num(3.0)
    ('12.3457', '1e-12', '-', '3')
    """
    if value is None:
        return "-"
    return f"{float(value):.{digits}g}"


def num_within(value: float, error: float, digits: int = 6) -> str:
    """``value`` as :func:`num` prints it, to no more digits than ``error`` supports, with ``± error`` beside it where
    that is fewer than ``digits``. O(1).

    Examples
    --------
    >>> num_within(0.8352448407578126, 6.2e-6), num_within(0.8352448407578126, 1e-16)
    ('0.83524 ± 6e-06', '0.835245')
    """
    shown = supported_digits(value, error, digits)
    return num(value, shown) + (f" ± {error:.1g}" if shown < digits else "")


def numbers(values: Sequence[float] | np.ndarray, digits: int = 6) -> str:
    """A comma-separated list, as ``--mu`` takes it.

    Examples
    --------
    >>> numbers([0.9, 0.5])
    '0.9, 0.5'
    """
    return ", ".join(num(v, digits) for v in np.ravel(values))


def eigenvalues(eigs: np.ndarray, digits: int = 4) -> str:
    """Eigenvalues by descending modulus (the JSON's order), reals without an imaginary part.

    Examples
    --------
    >>> eigenvalues(np.array([0.5, 0.9 + 0.1j, 0.9 - 0.1j, -1.0]))
    '-1, 0.9+0.1j, 0.9-0.1j, 0.5'
    """
    out = []
    for re, im in eigenvalue_pairs(np.asarray(eigs, dtype=complex)):
        out.append(num(re, digits) if im == 0 else f"{num(re, digits)}{float(im):+.{digits}g}j")
    return ", ".join(out)


def fields(pairs: Sequence[tuple[str, Any]], indent: str = INDENT) -> list[str]:
    """Aligned ``label  value`` lines; a value that is a list of lines goes below its label, indented.

    Examples
    --------
    >>> print("\\n".join(fields([("J*", "2.8"), ("method", "dense")])))
      J*              2.8
      method          dense
    """
    lines: list[str] = []
    for label, value in pairs:
        if isinstance(value, list):
            lines.append(f"{indent}{label}")
            lines += [f"{indent}{INDENT}{line}" for line in value]
        else:
            lines.append(f"{indent}{label:<{LABEL_WIDTH - 1}} {value}")
    return lines


def table(header: Sequence[str], rows: Sequence[Sequence[Any]], right: Sequence[bool] | None = None) -> list[str]:
    """Columns aligned under a header (numbers right-aligned when ``right`` says so).

    Examples
    --------
    >>> print("\\n".join(table(["id", "n"], [["a", 1], ["bb", 22]], right=[False, True])))
    id   n
    a    1
    bb  22
    """
    cells = [[str(h) for h in header]] + [[str(c) for c in row] for row in rows]
    widths = [max(len(row[k]) for row in cells) for k in range(len(header))]
    right = right or [False] * len(header)
    return ["  ".join((c.rjust(w) if r else c.ljust(w)) for c, w, r in zip(row, widths, right, strict=True)).rstrip()
            for row in cells]


def matrix(values: np.ndarray, rows: Sequence[str], cols: Sequence[str], digits: int = 6,
           max_rows: int = MAX_ROWS, max_cols: int = MAX_COLUMNS) -> list[str]:
    """A matrix with labelled rows and columns, numbers aligned on the right; beyond ``max_rows``
    rows or ``max_cols`` columns, the first ones and a line saying what was left out.

    Examples
    --------
    >>> print("\\n".join(matrix(np.array([[1.0, -0.25], [10.5, 2.0]]), ["u1", "u2"], ["x1", "x2"])))
          x1     x2
    u1     1  -0.25
    u2  10.5      2
    >>> matrix(np.eye(30), labels("t", 30), labels("x", 30))[-1]
    '(the first 20 of 30 rows and 8 of 30 columns; --json for all)'
    """
    values = np.atleast_2d(values)
    shown = values[:max_rows, :max_cols]
    body = [[str(r)] + [num(v, digits) for v in row] for r, row in zip(rows, shown, strict=False)]
    lines = table([""] + list(cols)[:max_cols], body, right=[False] + [True] * shown.shape[1])
    left_out = [f"{k} of {total} {what}" for k, total, what in zip(shown.shape, values.shape, ("rows", "columns"),
                                                                    strict=True) if k < total]
    if left_out:
        lines.append(f"(the first {' and '.join(left_out)}; --json for all)")
    return lines


def labels(prefix: str, count: int) -> list[str]:
    """``prefix1 .. prefixN``.

    Examples
    --------
    >>> labels("x", 3)
    ['x1', 'x2', 'x3']
    """
    return [f"{prefix}{k + 1}" for k in range(count)]
