"""User-given text (a system's name, a path, an option's value) made safe to print on a terminal.

Imports nothing: the command line uses it before NumPy is imported (``--help``, usage errors).
"""

from __future__ import annotations

__all__ = ["printable"]


def printable(text: str, keep: str = "") -> str:
    r"""``text`` with every non-printable character (C0 and C1 controls: ESC, BEL, newline, carriage return;
    DEL; Unicode separators and format characters) shown as its Python escape (``\x1b``, ``\n``,
    ``\u2028``), except those in ``keep``: a user-given name or path cannot recolour or ring a terminal,
    move its cursor, or add a line to the output. O(len(text)).

    Examples
    --------
    >>> print(printable("ev\x1b[31mil\nline\x07"))
    ev\x1b[31mil\nline\x07
    >>> printable("two lines\n\x1b", keep="\n") == "two lines\n\\x1b", printable("µ = 0.5, ü")
    (True, 'µ = 0.5, ü')
    """
    if text.isprintable():
        return text
    return "".join(ch if ch.isprintable() or ch in keep else repr(ch)[1:-1] for ch in text)
