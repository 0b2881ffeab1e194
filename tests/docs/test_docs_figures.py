"""Every figure in docs/figures (tutorials/ aside: tutorial_outputs.py draws those) is named in
docs/extensions/figures.py, with the code that draws it or as one of reproduce's, so each can be redrawn."""

import importlib.util
from pathlib import Path

from packetloss_cvx.cli.reproduce_report import BEYOND_FIGURES
from packetloss_cvx.cli.reproduce_report import FIGURES as PAPER_FIGURES

ROOT = Path(__file__).resolve().parents[2]
_spec = importlib.util.spec_from_file_location("docs_figures", ROOT / "docs" / "extensions" / "figures.py")
figures = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(figures)


def test_every_docs_figure_is_named_in_the_figures_script():
    shown = {p.name for p in (ROOT / "docs" / "figures").glob("*.png")}
    assert shown == set(figures.FIGURES)


def test_a_figure_without_code_in_the_script_is_one_reproduce_writes():
    written = {f"{label.removeprefix('fig:')}.png" for label in PAPER_FIGURES} | {f"{n}.png" for n in BEYOND_FIGURES}
    copied = {name for name, make in figures.FIGURES.items() if make is None}
    assert copied == set(figures.REPRODUCED)
    assert copied <= written
    assert all(callable(make) for name, make in figures.FIGURES.items() if name not in copied)
