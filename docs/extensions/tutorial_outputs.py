"""The tutorials' outputs: run each page's Python blocks in order, in one namespace (as a reader pastes them), and
show under each block what it printed and the figures it drew.

    python docs/extensions/tutorial_outputs.py [PAGE ...]     # rewrite the pages' outputs and figures

A block's output follows it as a ``text`` block titled "Output"; each figure a block draws follows as an image
``../figures/tutorials/<page>-<block>-<figure>.png``. Rerunning replaces what a previous run wrote (and only that).
tests/docs/test_docs.py runs the same pages and checks that every shown output is what the code prints today, its
numbers as the BLAS kernels move them, and that every figure the code draws is shown.
"""

from __future__ import annotations

import contextlib
import io
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path

DOCS = Path(__file__).resolve().parents[1]
FIGURES = DOCS / "figures" / "tutorials"
#: the pages whose outputs are shown (getting-started shows command lines, checked by its own tests)
PAGES = ("tutorials/design-study.md", "tutorials/formula-vs-solver.md", "tutorials/allocation-constraints.md",
         "tutorials/lossy-sensors.md", "tutorials/own-plant.md", "tutorials/saturating-actuators.md")

#: a Python block, then what a previous run wrote after it: an Output block, then its figures
BLOCK = re.compile(r"```python\n(?P<code>.*?)```\n"
                   r"(?P<shown>(?:\n```text title=\"Output\"\n(?P<output>.*?)```\n)?"
                   r"(?P<images>(?:\n!\[[^\]]*\]\(\.\./figures/tutorials/[\w.-]+\.png\)\n)*))", re.S)


@dataclass
class Block:
    """One Python block of a page: its code, what the page shows under it, and (once run) what it printed and
    which figures it drew (pyplot's, and the Figures or Axes it bound to a name)."""

    code: str
    shown_output: str | None
    shown_images: list[str]
    printed: str = ""
    figures: list = field(default_factory=list)


def blocks(text: str) -> list[Block]:
    """The page's Python blocks with what the page shows under each."""
    return [Block(m["code"], m["output"], re.findall(r"\(\.\./figures/tutorials/([\w.-]+\.png)\)", m["images"]))
            for m in BLOCK.finditer(text)]


def run(page: str, text: str | None = None) -> list[Block]:
    """Run the page's blocks in order in one namespace, in the current folder; each block's stdout and the
    matplotlib figures it left open (closed after recording). The caller chooses the folder the page may write in."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    plt.close("all")
    seen: set[int] = set()
    found = blocks((DOCS / page).read_text(encoding="utf-8") if text is None else text)
    namespace: dict = {"__name__": "__tutorial__"}
    for block in found:
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            exec(compile(block.code, page, "exec"), namespace)   # noqa: S102 - the page's own code
        block.printed = out.getvalue()
        drawn = [plt.figure(k) for k in plt.get_fignums()]      # pyplot's, and those a result's .plot() returned
        drawn += [v.figure if isinstance(v, Axes) else v for v in namespace.values() if isinstance(v, (Axes, Figure))]
        block.figures = []
        for fig in drawn:
            if id(fig) not in seen:
                seen.add(id(fig))
                block.figures.append(fig)
        plt.close("all")
    return found


def image_name(page: str, block: int, figure: int) -> str:
    return f"{Path(page).stem}-{block + 1}-{figure + 1}.png"


def caption(fig) -> str:
    """A figure's words for its image: its suptitle or first axes title."""
    titles = [fig.get_suptitle()] if fig.get_suptitle() else []
    titles += [ax.get_title() for ax in fig.axes if ax.get_title()]
    return re.sub(r"[\[\]$\\]", "", titles[0]) if titles else "Figure"


def rewrite(page: str) -> None:
    """Run the page and write its outputs and figures into it (atomically: the page is replaced whole)."""
    path = DOCS / page
    text = path.read_text(encoding="utf-8")
    ran = iter(run(page, text))
    FIGURES.mkdir(parents=True, exist_ok=True)
    for old in FIGURES.glob(f"{Path(page).stem}-*.png"):
        old.unlink()
    counter = iter(range(10_000))

    def shown(match: re.Match) -> str:
        block, k = next(ran), next(counter)
        parts = [f"```python\n{match['code']}```\n"]
        if block.printed.strip():
            parts.append(f"\n```text title=\"Output\"\n{block.printed.rstrip()}\n```\n")
        for j, fig in enumerate(block.figures):
            name = image_name(page, k, j)
            fig.savefig(FIGURES / name, dpi=80)
            parts.append(f"\n![{caption(fig)}](../figures/tutorials/{name})\n")
        return "".join(parts)

    new = BLOCK.sub(shown, text)
    tmp = path.with_suffix(".md.tmp")
    tmp.write_text(new, encoding="utf-8")
    tmp.replace(path)


if __name__ == "__main__":
    import os
    import tempfile

    pages = sys.argv[1:] or PAGES
    home = os.getcwd()
    with tempfile.TemporaryDirectory() as scratch:     # files a page writes land here, not in the checkout
        os.chdir(scratch)
        try:
            for page in pages:
                rewrite(page)
                print(f"rewrote {page}")
        finally:
            os.chdir(home)
