"""The documentation site's pages: their tutorials' code runs and shows what it prints and draws, and the nav names
every page (the strict build and
the browser check: tests/docs/test_docs_site.py)."""

import importlib.util
import re
import shlex
import sys
from pathlib import Path

import pytest

from packetloss_cvx.cli import main
from packetloss_cvx.tolerances import KERNEL_VALUE_RTOL, KERNEL_ZERO_ATOL

ROOT = Path(__file__).resolve().parents[2]
_spec = importlib.util.spec_from_file_location("tutorial_outputs", ROOT / "docs" / "extensions" / "tutorial_outputs.py")
tutorial_outputs = sys.modules["tutorial_outputs"] = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(tutorial_outputs)
PAGES = ["getting-started.md", *tutorial_outputs.PAGES]


def python_blocks(page: str) -> list[str]:
    return re.findall(r"```python\n(.*?)```", (ROOT / "docs" / page).read_text(encoding="utf-8"), flags=re.S)


@pytest.mark.parametrize("page", PAGES)
def test_tutorial_code_runs(page, capsys, monkeypatch, tmp_path):
    """Each page's Python blocks, in order, in one namespace (as a reader pastes them); their asserts check."""
    blocks = python_blocks(page)
    assert blocks, f"{page} has no Python block"
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "__tutorial__"}
    for block in blocks:
        exec(compile(block, page, "exec"), namespace)   # noqa: S102 - the page's own code
    assert capsys.readouterr().out       # each page prints what it shows


def test_nav_names_every_page():
    nav = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    pages = {p.relative_to(ROOT / "docs").as_posix() for p in (ROOT / "docs").rglob("*.md")}
    assert pages == set(re.findall(r":\s*([\w/-]+\.md)\s*$", nav, flags=re.M))


GETTING_STARTED = (ROOT / "docs" / "getting-started.md").read_text(encoding="utf-8")
#: the files the page asks the reader to save (a fenced block titled with the file's name) -> their text
FILES = dict(re.findall(r'^```\w+ title="([^"]+)"\n(.*?)^```', GETTING_STARTED, flags=re.S | re.M))
#: the page's command lines, as typed (a ``$`` prompt; a trailing comment is the page's, not the shell's)
COMMANDS = [shlex.split(line[2:], comments=True) for block in re.findall(r"```console\n(.*?)```", GETTING_STARTED,
                                                                           flags=re.S)
            for line in block.splitlines() if line.startswith("$ ")]


def run(argv: list[str]) -> int:
    """``packetloss-cvx ARGS`` in this process: its exit status (argparse's --help exits through SystemExit)."""
    assert argv[0] == "packetloss-cvx"
    try:
        return main(argv[1:])
    except SystemExit as stop:
        return stop.code


def test_getting_started_provides_the_files_its_commands_read():
    """Every file a command reads (``--mu-schedule FILE``, ``--mu-list FILE``) is given on the page."""
    assert COMMANDS
    read = {argv[i + 1] for argv in COMMANDS for i, word in enumerate(argv[:-1])
            if word in ("--mu-schedule", "--mu-list", "--constraint-file")}
    assert read == {"mu.csv"}
    assert read <= set(FILES)


@pytest.mark.parametrize("argv", COMMANDS, ids=" ".join)
def test_getting_started_command_runs_word_for_word(argv, monkeypatch, capsys, tmp_path):
    """Each command as the page types it, in a folder holding only the files the page gives."""
    monkeypatch.chdir(tmp_path)
    for name, text in FILES.items():
        (tmp_path / name).write_text(text, encoding="utf-8")
    assert run(argv) == 0
    assert capsys.readouterr().out


NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")


def _unit(token: str) -> float:
    """One unit in the last printed digit ('5.1e-15': 1e-16; '0.746502': 1e-6; an integer: 0, compared exactly)."""
    mantissa, _, exponent = token.lower().partition("e")
    return 10.0 ** (int(exponent or 0) - len(mantissa.partition(".")[2])) if "." in mantissa else 0.0


def _agree(shown: str, fresh: str) -> bool:
    """Two printed numbers of one quantity: both rounding-level (a cross-check's residuals, zero in exact arithmetic:
    below KERNEL_ZERO_ATOL), or within KERNEL_VALUE_RTOL of the larger plus one unit in the last printed digit."""
    a, b = float(shown), float(fresh)
    if abs(a) < KERNEL_ZERO_ATOL and abs(b) < KERNEL_ZERO_ATOL:
        return True
    return abs(a - b) <= min(_unit(shown), _unit(fresh)) + KERNEL_VALUE_RTOL * max(abs(a), abs(b))


def test_getting_started_sample_output_is_what_solve_prints(capsys, monkeypatch, tmp_path):
    """The page's sample is the start of ``packetloss-cvx solve two_actuator``'s output today: the same lines, their
    words exactly, their numbers as the kernels move them (a line added to the output, as the closed-loop verdict
    was, shows here)."""
    monkeypatch.chdir(tmp_path)
    (sample,) = re.findall(r"```text\n(.*?)```", GETTING_STARTED, flags=re.S)
    assert "packetloss-cvx solve two_actuator`'s output" in GETTING_STARTED
    assert run(["packetloss-cvx", "solve", "two_actuator"]) == 0
    printed = capsys.readouterr().out.splitlines()
    shown = sample.rstrip("\n").splitlines()
    assert len(printed) > len(shown)
    for k, (line, fresh) in enumerate(zip(shown, printed, strict=False)):
        assert NUMBER.split(line) == NUMBER.split(fresh), (k, line, fresh)
        for a, b in zip(NUMBER.findall(line), NUMBER.findall(fresh), strict=True):
            assert _agree(a, b), (k, a, b)
    assert printed[len(shown)] == "", "the sample stops inside a block"


@pytest.mark.parametrize("page", tutorial_outputs.PAGES)
def test_tutorial_shows_what_its_code_prints_and_draws(page, monkeypatch, tmp_path):
    """Under each Python block, the page shows what the block prints today (the same words; numbers as the kernels
    move them) and one image for each figure it draws, and every image it shows exists; a block that prints nothing
    shows no output. Regenerate with ``python docs/extensions/tutorial_outputs.py``."""
    monkeypatch.chdir(tmp_path)
    ran = tutorial_outputs.run(page)
    assert any(block.printed for block in ran), f"{page} prints nothing"
    for k, block in enumerate(ran):
        shown = (block.shown_output or "").rstrip("\n").splitlines()
        printed = block.printed.rstrip("\n").splitlines()
        assert len(shown) == len(printed), (page, k, shown, printed)
        for line, fresh in zip(shown, printed, strict=True):
            assert NUMBER.split(line) == NUMBER.split(fresh), (page, k, line, fresh)
            for a, b in zip(NUMBER.findall(line), NUMBER.findall(fresh), strict=True):
                assert _agree(a, b), (page, k, a, b)
        assert block.shown_images == [tutorial_outputs.image_name(page, k, j) for j in range(len(block.figures))]
        for name in block.shown_images:
            assert (ROOT / "docs" / "figures" / "tutorials" / name).is_file(), name
