"""A griffe extension for the API pages: a docstring's ``.. math::`` directive (numpydoc, as scipy writes it) becomes
a displayed formula for ``pymdownx.arithmatex``, which MathJax typesets. The docstrings keep the numpydoc form that
``help()`` and an editor show; only the rendered page changes.

``.. math:: formula`` on one line, or the directive followed by an indented block (its first line on the directive's
line or on the next ones), becomes ``\\[ formula \\]`` at the directive's indentation."""

import re

import griffe

DIRECTIVE = re.compile(r"^(?P<indent>[ \t]*)\.\. math::[ \t]*(?P<first>.*)$")


def _indent(line: str) -> int:
    return len(line) - len(line.lstrip())


def convert(text: str) -> str:
    """``text`` with every ``.. math::`` directive written as an arithmatex display block."""
    lines = text.split("\n")
    out: list[str] = []
    i = 0
    while i < len(lines):
        match = DIRECTIVE.match(lines[i])
        if match is None:
            out.append(lines[i])
            i += 1
            continue
        indent = match["indent"]
        body = [match["first"].strip()] if match["first"].strip() else []
        i += 1
        while i < len(lines) and (not lines[i].strip() or _indent(lines[i]) > len(indent)):
            if not lines[i].strip() and body and (i + 1 >= len(lines) or _indent(lines[i + 1]) <= len(indent)):
                break                                       # a blank line after the block ends it
            if lines[i].strip():
                body.append(lines[i].strip())
            i += 1
        out += ["", f"{indent}\\[", *(f"{indent}{line}" for line in body), f"{indent}\\]", ""]
    return "\n".join(out)


class SphinxMath(griffe.Extension):
    """Rewrites ``.. math::`` in every docstring griffe loads."""

    def on_instance(self, *, node, obj, agent, **kwargs) -> None:  # noqa: ARG002 - griffe's hook signature
        if obj.docstring is not None and ".. math::" in obj.docstring.value:
            obj.docstring.value = convert(obj.docstring.value)
