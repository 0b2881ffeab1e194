"""The command line feels native: fast help and errors (structurally: what they import), --version,
help on every option, scalar --mu, --mu-schedule, --out, -q/-v everywhere, one text style."""

import argparse
import ast
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.cli import main
from packetloss_cvx.cli.common import progress_of
from packetloss_cvx.cli.parser import add_command, build_parser
from packetloss_cvx.optional import LAZY_IMPORTS

from ..processes import Zygote

#: what --help, usage errors and bad input must not import: the heavy optional libraries (the package's one
#: list, packetloss_cvx.optional) and SciPy (required, but nothing numerical runs before the input is checked)
HEAVY = frozenset(LAZY_IMPORTS) | {"scipy"}

PROBE = f"""
import sys
from packetloss_cvx.cli import main
try:
    code = main(sys.argv[1:])
except SystemExit as exit_:
    code = exit_.code
print("MODULES", sorted({{m for m in sys.modules if m.split(".")[0] in {sorted(HEAVY | {"numpy"})!r}}}))
"""


@pytest.fixture(scope="module")
def zygote():
    """The parent every probe is forked from (tests/processes.py): it imported only packetloss_cvx.cli, the
    probe's first import, and none of the probed packages (a planted eager import there fails here)."""
    with Zygote(["packetloss_cvx.cli"]) as parent:
        assert "packetloss_cvx" in parent.modules
        assert not parent.modules & (HEAVY | {"numpy"}), sorted(parent.modules & (HEAVY | {"numpy"}))
        yield parent


def imported(zygote, *argv):
    """The probed packages' modules loaded by ``python -c PROBE argv`` (forked from the zygote)."""
    proc = zygote.run(list(argv), code=PROBE)
    line = [ln for ln in proc.stdout.splitlines() if ln.startswith("MODULES")][-1]
    return set(ast.literal_eval(line.removeprefix("MODULES ")))


@pytest.mark.parametrize("argv", [["--help"], ["--version"], ["solve", "--help"],
                                  ["audit", "--help"], ["allocate", "--help"], ["solve"], ["frobnicate"]])
def test_help_version_and_usage_errors_import_nothing_numerical(zygote, argv):
    modules = imported(zygote, *argv)
    assert not modules, f"{argv} imported {sorted(modules)[:5]}"


@pytest.mark.parametrize("shell", ["bash", "zsh"])
def test_completion_imports_shtab_and_nothing_numerical(zygote, shell):
    assert imported(zygote, "--completion", shell) == {"shtab"}


@pytest.mark.parametrize("argv", [["solve", "no-such-file.toml"], ["solve", "two_actuator", "--mu", "2"],
                                  ["solve", "two_actuator", "--mu", "x"], ["audit", "--random", "-1"],
                                  ["allocate", "two_actuator", "--protocol", "udp", "--alpha", "8", "--beta", "1"]])
def test_bad_input_imports_numpy_only(zygote, argv):
    modules = imported(zygote, *argv)
    assert not {m for m in modules if m.split(".")[0] in HEAVY}, sorted(modules)[:5]
    assert "numpy" in modules       # the probe sees what it should: loading a file needs NumPy


def run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_version(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0
    assert capsys.readouterr().out.strip() == f"packetloss-cvx {pl.__version__}"


def subcommands(parser):
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return action.choices


def test_every_option_has_help_with_default_and_example():
    for name, command in subcommands(build_parser()).items():
        for action in command._actions:
            if isinstance(action, argparse._HelpAction):
                continue
            assert action.help, f"{name} {action.dest}: no help"
            if action.option_strings and action.nargs != 0 and not action.choices and action.dest != "verbose":
                shown = command.formatter_class(prog="x")._get_help_string(action) % {"default": action.default}
                assert "e.g." in shown, f"{name} {action.option_strings}: no example"
                assert "default" in shown or "required" in shown, f"{name} {action.option_strings}: no default"


def test_top_level_help_names_the_design_file(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    assert "docs/design.md" in out
    assert "DESIGN.md" not in out
    assert "exit codes" in out


@pytest.mark.parametrize("flag", ["-q", "--quiet", "-v", "--verbose"])
def test_quiet_and_verbose_on_every_subcommand(flag):
    parser = build_parser()
    for name, command in subcommands(parser).items():
        actions = {s for a in command._actions for s in a.option_strings}
        assert flag in actions, f"{name} has no {flag}"


def test_quiet_turns_progress_off_and_is_exclusive_with_verbose(capsys):
    parser = build_parser()
    assert progress_of(parser.parse_args(["audit", "-q"])) is False
    assert progress_of(parser.parse_args(["audit"])) is None
    assert main(["audit", "-q", "-v"]) == 2
    assert "not allowed with" in capsys.readouterr().err


def test_add_command_gives_a_new_subcommand_the_shared_options():
    parser = argparse.ArgumentParser()
    sub = parser.add_subparsers(dest="command")
    new = add_command(sub, "simulate", "sample", examples=["simulate two_actuator"])
    new.add_argument("file")
    args = parser.parse_args(["simulate", "f", "-q", "--json", "--out", "x.json"])
    assert (args.quiet, args.json, args.json_out, args.verbose) == (True, True, "x.json", 0)
    dirs = add_command(sub, "sweep", "sweep", results=False)
    dirs.add_argument("--out", help="a directory")       # a command whose --out is a directory
    assert parser.parse_args(["sweep", "--out", "d"]).out == "d"
    assert "packetloss-cvx simulate two_actuator" in new.format_help()


def test_scalar_mu_means_every_channel(capsys):
    code, out, _ = run(capsys, "solve", "two_actuator", "--mu", "0.5", "--no-qp", "--json")
    assert code == 0
    data = json.loads(out)
    assert data["mu"] == [0.5, 0.5]
    reference = pl.closed_form(pl.load_example("two_actuator").with_mu([0.5, 0.5]), "udp").cost
    assert data["udp"]["cost"] == pytest.approx(reference, rel=1e-12)


def test_mu_schedule_csv(capsys, tmp_path):
    rng = np.random.default_rng(13)
    schedule = rng.uniform(0.1, 1.0, size=(10, 2))
    path = tmp_path / "mu.csv"
    path.write_text("# t = 0..9, two channels\n" + "\n".join(",".join(repr(float(v)) for v in row) for row in schedule))
    code, out, _ = run(capsys, "solve", "two_actuator", "--mu-schedule", str(path), "--no-qp", "--json")
    assert code == 0
    data = json.loads(out)
    assert np.array_equal(np.array(data["mu"]), schedule)
    system = pl.System(**{**_keywords(pl.load_example("two_actuator")), "mu_schedule": schedule})
    assert data["tcp"]["cost"] == pytest.approx(pl.closed_form(system, "tcp", method="recursion").cost, rel=1e-10)


def _keywords(system):
    return dict(A=system.A, B=system.B, horizon=system.horizon, state_weights=system.state_weights,
                input_weights=system.input_weights, x0=system.x0, initial_weight=system.initial_weight,
                noise_cov=system.noise_cov)


@pytest.mark.parametrize(("content", "argv", "match"), [
    ("0.5,0.5\n" * 9, [], "--mu-schedule: expected shape (10, 2)"),
    ("0.5,0.5\n" * 9 + "0.5,x\n", [], "--mu-schedule: line 10: expected numbers, found '0.5,x'"),
    ("0.5,0.5\n" * 9 + "0.5,1.5\n", [], "--mu-schedule: line 10: expected probabilities in [0, 1], found 1.5"),
    (None, [], "--mu-schedule: cannot read"),
    ("0.5,0.5\n" * 10, ["--mu", "0.5"], "not allowed with"),
])
def test_bad_mu_schedule_exit_2_one_line(capsys, tmp_path, content, argv, match):
    path = tmp_path / "mu.csv"
    if content is not None:
        path.write_text(content)
    code, out, err = run(capsys, "solve", "two_actuator", "--mu-schedule", str(path), *argv)
    assert code == 2
    assert out == ""
    assert err.count("\n") == 1
    assert match in err


def test_out_writes_the_json_object(capsys, tmp_path):
    path = tmp_path / "result.json"
    code, text, _ = run(capsys, "solve", "two_actuator", "--no-qp", "--out", str(path))
    assert code == 0
    assert "TCP-like" in text                              # the text still goes to stdout
    code, out, _ = run(capsys, "solve", "two_actuator", "--no-qp", "--json")
    assert json.loads(path.read_text()) == json.loads(out)
    code, _, err = run(capsys, "solve", "two_actuator", "--no-qp", "--out", str(tmp_path / "no" / "dir.json"))
    assert code == 2
    assert err.startswith("packetloss-cvx: error: --out: cannot write")


def test_verbose_reports_time_and_the_plan(capsys):
    code, out, err = run(capsys, "solve", "two_actuator", "--no-qp", "-v", "--protocol", "tcp")
    assert code == 0
    assert "U* (row t)" in out
    assert "t=9" in out
    assert "solve took" in err


def test_text_output_matrices_and_eigenvalues(capsys):
    """Rows of K labelled and aligned; real eigenvalues printed as reals, in the JSON's order."""
    code, out, _ = run(capsys, "solve", "two_actuator", "--no-qp", "--protocol", "tcp")
    assert code == 0
    lines = out.splitlines()
    k = lines.index("  K (u = -K x)")
    header, row1, row2 = lines[k + 1: k + 4]
    assert header.split() == ["x1", "x2"]
    assert row1.split()[0] == "u1"
    assert row2.split()[0] == "u2"
    assert len(row1) == len(row2) == len(header)        # right-aligned columns end together
    gain = pl.closed_form(pl.load_example("two_actuator"), "tcp").gain
    assert [float(v) for v in row1.split()[1:]] == pytest.approx(gain[0], rel=1e-5)
    eig_line = next(ln for ln in lines if ln.strip().startswith("eig(A - B K)"))
    shown = [float(v) for v in eig_line.split("eig(A - B K)")[1].split(",")]   # reals: no "j"
    code, out, _ = run(capsys, "solve", "two_actuator", "--no-qp", "--protocol", "tcp", "--json")
    pairs = json.loads(out)["tcp"]["closed_loop_eigenvalues"]
    assert all(im == 0 for _, im in pairs)
    assert shown == pytest.approx([re for re, _ in pairs], rel=1e-3)
    expected = np.linalg.eigvals(np.array([[1.03, 0.005], [0.35, 1.01]]) - gain)   # B = I in the example
    assert sorted(np.abs(shown), reverse=True) == pytest.approx(np.abs(shown))
    assert sorted(np.abs(expected), reverse=True) == pytest.approx(np.abs(shown), rel=1e-3)


def test_audit_text_is_an_aligned_table(capsys):
    code, out, _ = run(capsys, "audit", "--random", "0", "--claim", "theorem-2", "--claim", "table-2", "-q")
    assert code == 0
    lines = out.splitlines()
    assert lines[0].startswith("2 claims:")
    header = lines[2]
    assert header.split()[:2] == ["claim", "verdict"]
    assert [ln.split()[0] for ln in lines[3:5]] == ["theorem-2", "table-2"]
    assert len({ln.index(ln.split()[1]) for ln in lines[2:5]}) == 1     # the verdict column is aligned


def test_progress_bars_by_default_on_a_terminal_as_tqdms_disable_none(monkeypatch):
    import io

    import tqdm

    from packetloss_cvx.progress import progress_bar

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    for stream, shown in ((Terminal(), True), (io.StringIO(), False)):
        monkeypatch.setattr(sys, "stderr", stream)
        with progress_bar(range(3), desc="work") as bar:
            assert list(bar) == [0, 1, 2]
        assert ("work" in stream.getvalue()) == shown
        reference = tqdm.tqdm(range(3), file=stream, disable=None)     # tqdm's own rule for the same stream
        assert bool(reference.disable) == (not shown)
        reference.close()


def test_progress_bars_on_request_and_never_by_default_in_a_pipe(capsys):
    from packetloss_cvx.claims import audit
    from packetloss_cvx.studies.allocation import pareto_curve

    system = pl.load_example("two_actuator")
    audit(random=0, only=["theorem-2"], progress=True)
    assert "audit" in capsys.readouterr().err
    audit(random=0, only=["theorem-2"])                 # stderr is captured here: not a terminal
    assert capsys.readouterr().err == ""
    rows = pareto_curve(system, "tcp", (1.0, 1.0), [8.0, 10.0], progress=True)
    assert "Pareto" in capsys.readouterr().err
    assert rows == pareto_curve(system, "tcp", (1.0, 1.0), [8.0, 10.0], progress=False)
    assert capsys.readouterr().err == ""


def completion_script(capsys, shell):
    with pytest.raises(SystemExit) as stop:
        main(["--completion", shell])
    assert stop.value.code == 0
    return capsys.readouterr().out


#: a word typed, the words bash offers (in a folder holding plant.toml only)
COMPLETIONS = [
    (["solve", "--protocol", "u"], ["udp"]),
    (["al"], ["allocate"]),
    (["audit", "--cl"], ["--claim"]),
    (["sweep", "two_actuator", "--mu-"], ["--mu-grid", "--mu-list"]),
    (["solve", "pend"], ["pendulum", "pendulum_bursty", "pendulum_sensor"]),
    (["simulate", ""], [*sorted(p.stem for p in (Path(pl.__file__).parent / "model" / "examples").glob("*.toml")), "plant.toml"]),
    (["allocate", "pl"], ["plant.toml"]),
]


def test_bash_completion_completes_commands_options_choices_and_every_packaged_example(capsys, tmp_path):
    script = completion_script(capsys, "bash")
    for command in subcommands(build_parser()).values():
        assert all(flag in script for action in command._actions for flag in action.option_strings)
    if shutil.which("bash") is None:
        pytest.skip("no bash to run the script")
    (tmp_path / "complete.sh").write_text(script)
    (tmp_path / "work").mkdir()
    (tmp_path / "work" / "plant.toml").write_text("")
    probe = [f"source '{tmp_path / 'complete.sh'}'",
             't() { COMP_WORDS=("$@"); COMP_CWORD=$(( ${#COMP_WORDS[@]} - 1 )); '
             'COMP_LINE="$*"; COMP_POINT=${#COMP_LINE}; COMPREPLY=(); _shtab_packetloss_cvx; echo "${COMPREPLY[*]}"; }']
    probe += ["t packetloss-cvx " + " ".join(f"'{w}'" for w in words) for words, _ in COMPLETIONS]
    proc = subprocess.run(["bash", "-c", "\n".join(probe)], capture_output=True, text=True, check=True,
                          cwd=tmp_path / "work")
    assert [line.split() for line in proc.stdout.splitlines()] == [want for _, want in COMPLETIONS]


#: zsh driving one interactive zsh on a pseudo-terminal: the completion loaded by compinit from $1, in the folder
#: $2; then for each pair (line, text) after them, the line typed with a TAB, the screen read until it shows the
#: text (or 30 s pass), the line aborted and a marker command run: every byte the completion wrote comes before the
#: marker's output (``DONE42-k``; the typed line echoes ``DONE$((6*7))-k``), so each line's screen is read whole
#: without a fixed sleep. Prints each line's screen followed by a line ZSH_SCREEN_END.
ZSH_SCREEN_END = "=== end of screen ==="
ZSH_PROBE = r"""
zmodload zsh/zpty
zmodload zsh/zselect
zpty z 'zsh -f -i'
zpty -w z "PS1='> '; fpath=($1 \$fpath); autoload -Uz compinit; compinit -u -D; cd $2"
zpty -w z "zstyle ':completion:*' menu no; zstyle ':completion:*' list-prompt ''"
read_until() {
  local deadline=$(( SECONDS + 30 ))
  while [[ $out != *$1* ]] && (( SECONDS < deadline )); do
    if zpty -r -t z chunk; then out+=$chunk; else zselect -t 1; fi
  done
}
shift 2
k=0
while (( $# >= 2 )); do
  k=$(( k + 1 ))
  out=""
  zpty -wn z "$1"$'\t\t'
  read_until "$2"
  zpty -w z $'\C-c'
  zpty -w z "print DONE\$((6*7))-$k"
  read_until "DONE42-$k"
  print -r -- "$out"
  print -r -- "=== end of screen ==="
  shift 2
done
zpty -d z
"""

#: a line typed in zsh, what the screen must then show
ZSH_COMPLETIONS = [
    ("packetloss-cvx simulate pend", "pendulum_bursty"),                 # the examples listed
    ("packetloss-cvx solve pl", "packetloss-cvx solve plant.toml"),       # a file name completed
    ("packetloss-cvx sweep two_actuator --mu-g", "--mu-grid"),           # an option
]


def test_zsh_completion_completes_examples_files_and_options_in_zsh(capsys, tmp_path):
    script = completion_script(capsys, "zsh")
    assert script.startswith("#compdef packetloss-cvx")
    examples = sorted(p.stem for p in (Path(pl.__file__).parent / "model" / "examples").glob("*.toml"))
    assert f"'examples:example:({' '.join(examples)})'" in script
    if shutil.which("zsh") is None:
        pytest.skip("no zsh to run the script")
    (tmp_path / "fn").mkdir()
    (tmp_path / "fn" / "_packetloss-cvx").write_text(script)
    subprocess.run(["zsh", "-n", str(tmp_path / "fn" / "_packetloss-cvx")], check=True)
    (tmp_path / "work").mkdir()
    (tmp_path / "work" / "plant.toml").write_text("")
    # one shell types the lines in turn: compinit (most of a probe's 0.8 s) runs once, not once per line
    pairs = [text for pair in ZSH_COMPLETIONS for text in pair]
    proc = subprocess.run(["zsh", "-f", "-c", ZSH_PROBE, "probe", str(tmp_path / "fn"), str(tmp_path / "work"),
                           *pairs], capture_output=True, text=True, timeout=120, check=False,
                          env={"HOME": str(tmp_path), "PATH": "/usr/bin:/bin", "TERM": "dumb"})
    assert proc.returncode == 0, proc.stderr[-400:]
    screens = proc.stdout.split(ZSH_SCREEN_END + "\n")
    assert len(screens) == len(ZSH_COMPLETIONS) + 1, proc.stdout[-400:]
    assert not screens[-1].strip(), proc.stdout[-400:]
    for (line, shown), screen in zip(ZSH_COMPLETIONS, screens[:-1], strict=True):
        assert shown in screen, (line, screen[-400:])
        assert "bad option" not in screen, screen[-400:]       # no error from the completion functions
