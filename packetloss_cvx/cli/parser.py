"""The command line's grammar: argparse only, no numerical import (``--help`` stays fast).

Each subcommand names the module of this package that runs it (``command="solve"`` ->
``packetloss_cvx.cli.solve.run``); [`packetloss_cvx.cli.main`][packetloss_cvx.cli.main] imports that module only
when the command runs. A new subcommand is one block in [`build_parser`][packetloss_cvx.cli.parser.build_parser] and its
module::

    sim = add_command(sub, "simulate", "sample the closed loop",
                      examples=["simulate two_actuator --samples 1000 --seed 1"])
    mark_system_file(sim.add_argument("file", metavar="FILE", help=FILE_HELP))
    add_system_options(sim)                     # --mu, --mu-schedule, --x0, if it takes them
    sim.add_argument("--samples", type=int, default=1000, help="number of sample paths, e.g. 5000")

[`add_command`][packetloss_cvx.cli.parser.add_command] gives every subcommand the same shared options (``-q/--quiet``,
``-v/--verbose``, and unless ``results=False``: ``--json`` and ``--out FILE``), the same help
layout (each option's default appended to its help) and an "examples" epilog. A command whose
``--out`` names a directory (sweep, reproduce) passes ``results=False`` and adds its own
``--json`` and ``--out DIR``.
"""

from __future__ import annotations

import argparse
import re
from collections.abc import Sequence

from .. import __version__
from ..errors import InputError
from .completion import SHELLS, CompletionAction, mark_system_file

__all__ = ["FIGURE_FORMATS", "FILE_HELP", "NUMBER_LISTS", "add_command", "add_constraint_options", "add_figure_options",
           "add_system_options", "build_parser", "join_negative_values"]

#: Options whose value is a comma-separated list of numbers that may start with a minus sign.
NUMBER_LISTS = ("--mu", "--x0", "--beta", "--bounds", "--alpha", "--x0-scales", "--burstiness", "--direction",
                "--mean-rate", "--power-scale", "--power-max", "--budget", "--ack-price", "--ack-power", "--u-min",
                "--u-max", "--x-min", "--x-max", "--terminal-min", "--terminal-max", "--target")

FILE_HELP = ("a system file (TOML, docs/design.md §4) or a packaged example: pendulum, two_actuator, "
             "pendulum_bursty (a Gilbert-Elliott channel), pendulum_sensor (a lossy sensor link too)")

DESCRIPTION = f"""\
packetloss-cvx {__version__}: optimal control over multichannel packet-loss links
(Casbolt, Jones, Esnaola), every answer computed in closed form and cross-checked by a solver.

exit codes: 0 success; 1 a refused or failed computation; 2 bad input (one line naming
the field), or a count beyond its work budget (PACKETLOSS_CVX_BUDGET_<NAME> raises it:
docs/design.md §4); 3 proved infeasible; 4 allocation gap not certified within its caps.
Contracts (files, JSON keys): docs/design.md §4. Help on a command: packetloss-cvx COMMAND -h"""

EPILOG = """\
examples:
  packetloss-cvx solve two_actuator
  packetloss-cvx solve pendulum --protocol udp --mu 0.5 --json
  packetloss-cvx allocate two_actuator --protocol udp --alpha 8 --beta 1,0.05
  packetloss-cvx audit --random 20 --seed 1"""


class Formatter(argparse.RawDescriptionHelpFormatter):
    """Keeps the epilog's line breaks and appends ``(default: X)`` to an option whose default is set."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        default = action.default
        if (default is not None and default is not False and default != argparse.SUPPRESS and "default" not in text
                and action.option_strings and action.nargs != 0):
            text += " (default: %(default)s)"
        return text


class Parser(argparse.ArgumentParser):
    """argparse that reports a usage error as one line and exit code 2, under the option it is
    about when argparse names one ("argument --samples: invalid int value: '1e12'" is reported as
    ``--samples: invalid int value: '1e12'``), else under "arguments". An option is never guessed
    from a prefix (``allow_abbrev=False``): ``sweep FILE --x0 2,-1`` was read as ``--x0-scales 2,-1``
    (a sweep over x0 times 2 and -1) where ``solve --x0 2,-1`` sets x0; now it is an unknown option."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        kwargs.setdefault("allow_abbrev", False)     # subparsers are built by this class too
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]

    def error(self, message: str) -> None:  # type: ignore[override]
        head, sep, rest = message.partition(": ")
        if sep and head.startswith("argument ") and " " not in head[len("argument "):]:
            raise InputError(head[len("argument "):], rest)
        if sep and head == "unrecognized arguments" and rest.split():
            first = rest.split()[0].split("=")[0] if rest.startswith("-") else rest.split()[0]
            raise InputError(first, "not an option of this command (see its --help)" if first.startswith("-") else
                             f"unexpected argument (all given: {rest[:80]}); see the command's --help")
        raise InputError("arguments", message)


def shared_options(results: bool) -> argparse.ArgumentParser:
    """The options every subcommand has: verbosity and, for commands that return one result, its JSON."""
    parent = argparse.ArgumentParser(add_help=False)
    group = parent.add_argument_group("output")
    if results:
        group.add_argument("--json", action="store_true", help="print one JSON object on stdout instead of text")
        group.add_argument("--out", dest="json_out", metavar="FILE",
                           help="also write the JSON object to FILE (default: none), e.g. --out result.json")
    group.add_argument("--force", action="store_true",
                       help="replace an existing output FILE, or write into a folder holding files no "
                            "packetloss-cvx manifest lists (default: refuse, exit 2; docs/design.md §4)")
    loud = group.add_mutually_exclusive_group()
    loud.add_argument("-q", "--quiet", action="store_true", help="no progress bars on stderr")
    loud.add_argument("-v", "--verbose", action="count", default=0,
                      help="more detail: plans, notes, and the time taken on stderr")
    return parent


def add_command(sub: argparse._SubParsersAction, name: str, summary: str, *, examples: Sequence[str] = (),
                results: bool = True) -> argparse.ArgumentParser:
    """A subcommand with the shared options and an examples epilog; ``name`` is the module that runs it.

    Examples
    --------
    >>> parser = argparse.ArgumentParser()
    >>> new = add_command(parser.add_subparsers(dest="command"), "simulate", "sample", examples=["simulate pendulum"])
    >>> args = parser.parse_args(["simulate", "-q", "--json"])
    >>> args.command, args.quiet, args.json, args.verbose
    ('simulate', True, True, 0)
    """
    epilog = "examples:\n" + "\n".join(f"  packetloss-cvx {line}" for line in examples) if examples else None
    return sub.add_parser(name, help=summary, description=summary, epilog=epilog, formatter_class=Formatter,
                          parents=[shared_options(results)])


def add_system_options(command: argparse.ArgumentParser, schedule: bool = True) -> None:
    """``--mu``, ``--mu-schedule`` and ``--x0``: the file's channel and initial state overridden. A command that
    needs a stationary channel (its loop runs for ever over one channel: ``region``, ``compare``) passes
    ``schedule=False`` and has no ``--mu-schedule``.

    Examples
    --------
    >>> parser = Parser()
    >>> add_system_options(parser)
    >>> args = parser.parse_args(["--mu", "0.5", "--x0", "1,2"])
    >>> args.mu, args.mu_schedule, args.x0
    ('0.5', None, '1,2')
    >>> parser.parse_args(["--mu", "0.5", "--mu-schedule", "mu.csv"])     # one channel or the other
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: --mu-schedule: not allowed with argument --mu
    """
    group = command.add_argument_group("overrides of the file")
    channel = group.add_mutually_exclusive_group()
    channel.add_argument("--mu", metavar="MU",
                         help="delivery probabilities, one per actuator or one for all, e.g. --mu 0.9,0.5 or "
                              "--mu 0.5 (default: the file's)")
    if schedule:
        channel.add_argument("--mu-schedule", metavar="CSV",
                             help="a non-stationary channel: a CSV file of N rows of m probabilities, e.g. "
                                  "--mu-schedule mu.csv (default: the file's)")
    group.add_argument("--x0", metavar="X0",
                       help="the initial state, comma-separated, e.g. --x0 1,-1 (default: the file's)")


def add_constraint_options(command: argparse.ArgumentParser, what: str) -> None:
    """``--u-min``, ``--u-max``, ``--du-max``, ``--x-min``, ``--x-max``, ``--terminal-min``, ``--terminal-max``,
    ``--soft``/``--no-soft`` and ``--soft-weight``: keys of the file's ``[constraints]`` table replaced (or a table
    made); ``what`` says what the table does in this command.

    Examples
    --------
    >>> parser = Parser()
    >>> add_constraint_options(parser, "solved")
    >>> args = parser.parse_args(join_negative_values(["--u-min", "-1,-2", "--du-max", "0.5,inf", "--no-soft"]))
    >>> args.u_min, args.du_max, args.soft, args.x_max
    ('-1,-2', '0.5,inf', False, None)
    """
    group = command.add_argument_group(f"overrides of the file's [constraints] table ({what})")
    same = "default: the file's"
    group.add_argument("--u-min", metavar="U", help="bounds on each commanded input, m numbers or one for all, "
                                                    f"u_min <= 0 (a lost packet applies zero; {same}), "
                                                    "e.g. --u-min -1,-2")
    group.add_argument("--u-max", metavar="U", help=f"bounds on each commanded input, m numbers or one for all, "
                                                    f"u_max >= 0 ({same}), e.g. --u-max 1,2")
    group.add_argument("--du-max", metavar="DU", help="bound on |u_t - u_{t-1}|, m numbers or one for all, inf "
                                                      f"leaves an input out ({same}), e.g. --du-max 0.5,inf")
    group.add_argument("--x-min", metavar="X", help="lower limits on the expected state E[x_k], k = 1..N, n numbers "
                                                    f"or one for all ({same}), e.g. --x-min -2")
    group.add_argument("--x-max", metavar="X", help=f"upper limits on E[x_k], n numbers or one for all ({same}), "
                                                    "e.g. --x-max 2,inf")
    group.add_argument("--terminal-min", metavar="X", help="the terminal box on E[x_N] only, n numbers or one for "
                                                           f"all ({same}), e.g. --terminal-min -0.1")
    group.add_argument("--terminal-max", metavar="X", help=f"the terminal box on E[x_N] only ({same}), "
                                                           "e.g. --terminal-max 0.1")
    group.add_argument("--soft", action=argparse.BooleanOptionalAction,
                       help="state, terminal and chance rows as exact-penalty slacks (--soft) or hard (--no-soft) "
                            f"({same}, else hard), e.g. --soft")
    group.add_argument("--soft-weight", metavar="RHO",
                       help="the penalty per unit of violation of a soft row, > 0 and at most 1e8 times the largest "
                            f"cost weight ({same}, else 1e4), "
                            "e.g. --soft-weight 100")


def add_dask_options(command: argparse.ArgumentParser, what: str) -> None:
    """``--dask local|ADDRESS`` and ``--workers W`` (studies.engine.dask_client), as every command that runs on
    Dask takes them; ``what`` opens the --dask help (what runs there)."""
    command.add_argument("--dask", metavar="local|ADDRESS",
                         help=f"{what}: a new LocalCluster or a running scheduler (default: in process), "
                              "e.g. --dask tcp://127.0.0.1:8786")
    command.add_argument("--workers", type=int, metavar="W",
                         help="workers of --dask local (default: 2), e.g. --workers 4")


#: the figure formats every command that draws writes (``--format``)
FIGURE_FORMATS = ("png", "pdf", "svg")


def add_figure_options(command: argparse.ArgumentParser, what: str) -> None:
    """``--format png|pdf|svg`` and ``--dpi N``, as every command that draws takes them; ``what`` names the
    figures in the help.

    Examples
    --------
    >>> parser = Parser()
    >>> add_figure_options(parser, "the figures")
    >>> args = parser.parse_args(["--format", "svg", "--dpi", "300"])
    >>> args.format, args.dpi
    ('svg', 300.0)
    """
    group = command.add_argument_group("figures")
    group.add_argument("--format", choices=FIGURE_FORMATS,
                       help=f"the file format of {what} (default: png; with a FILE of its own: its extension), "
                            "e.g. --format pdf")
    group.add_argument("--dpi", type=float, metavar="N",
                       help=f"dots per inch of {what} (default: 120; the pixel size of a PNG, recorded in its "
                            "header; vector formats scale freely), e.g. --dpi 300")


def build_parser() -> argparse.ArgumentParser:
    """The whole grammar; ``args.command`` names the module that runs the subcommand.

    Examples
    --------
    >>> build_parser().parse_args(["solve", "pendulum", "--mu", "0.5"]).mu
    '0.5'
    """
    parser = Parser(prog="packetloss-cvx", description=DESCRIPTION, epilog=EPILOG, formatter_class=Formatter)
    parser.add_argument("-V", "--version", action="version", version=f"%(prog)s {__version__}")
    parser.add_argument("--completion", choices=SHELLS, action=CompletionAction,
                        help='print a shell completion script (bash or zsh), e.g. '
                             'eval "$(packetloss-cvx --completion bash)"')
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser, metavar="COMMAND")

    solve = add_command(sub, "solve", "optimal plans, costs and gains of both protocols, cross-checked by a QP",
                        examples=["solve two_actuator", "solve pendulum --protocol udp --mu 0.5 --json",
                                  "solve two_actuator --method recursion --x0 1,-1 --out result.json"])
    mark_system_file(solve.add_argument("file", metavar="FILE", help=FILE_HELP))
    solve.add_argument("--protocol", choices=("tcp", "udp", "both"), default="both",
                       help="TCP-like (acknowledged), UDP-like (not) or both, e.g. --protocol udp")
    add_system_options(solve)
    solve.add_argument("--method", choices=("dense", "recursion", "auto"), default="auto",
                       help="closed form: Theorem 1's dense formulas or the O(N) recursion; auto picks by size "
                            "and conditioning, e.g. --method recursion")
    solve.add_argument("--formulation", choices=("condensed", "sparse", "auto"), default="auto",
                       help="the cross-checking QP's form, e.g. --formulation sparse")
    solve.add_argument("--no-qp", action="store_true",
                       help="skip the solvers: the QP cross-check and a [constraints] table (closed form only)")
    add_constraint_options(solve, "solved beside the closed forms")
    solve.add_argument("--actuator", metavar="zero|hold|buffer[:L][:hold]|all",
                       help="what the actuator does on a loss, for each law's loop: apply zero, hold the last "
                            "input, or play the buffered plan of L inputs (default L: the horizon); comma-separated, "
                            "or all to compare the three: exact mean-square radius and cost over N steps "
                            "(default: none), e.g. --actuator all")
    solve.add_argument("--stability", action=argparse.BooleanOptionalAction,
                       help="each law's mean-square stability in closed loop: --stability computes it at any n "
                            "(minutes for n in the hundreds), --no-stability skips it (default: computed for "
                            "n <= 60, skipped with a note above)")

    aud = add_command(sub, "audit", "check every claim of the paper on its systems and random ones",
                      examples=["audit --random 20 --seed 1", "audit two_actuator --claim theorem-2 --random 0",
                                "audit --report > claims.md"])
    mark_system_file(aud.add_argument("files", nargs="*", metavar="FILE",
                                      help="more systems to check the claims on, e.g. pendulum"))
    aud.add_argument("--random", type=int, default=50, help="seeded random systems (>= 0), e.g. --random 200")
    aud.add_argument("--seed", type=int, default=0,
                     help="seeds the random systems, the samples and the shrinking (>= 0), e.g. --seed 1")
    aud.add_argument("--claim", action="append", metavar="ID",
                     help="check only this claim (repeatable; default: all), e.g. --claim theorem-2")
    aud.add_argument("--report", action="store_true",
                     help="the Markdown report with notes and counterexamples, as the text (not with --json; --out "
                          "FILE writes the JSON beside it)")

    alloc = add_command(sub, "allocate", "the cheapest channel qualities mu with J*(mu) <= alpha (paper §VI)",
                        examples=["allocate two_actuator --protocol udp --alpha 8 --beta 1,0.05",
                                  "allocate two_actuator --protocol tcp --alpha 8 --beta 1,1 "
                                  '--constraint "mu1 >= mu2"',
                                  "allocate two_actuator --protocol udp --alpha 8 --power exponential "
                                  "--power-scale 1,2",
                                  "allocate two_actuator --protocol best --alpha 8 --beta 1,1 --ack-price 0.2"])
    mark_system_file(alloc.add_argument("file", metavar="FILE", help=FILE_HELP))
    alloc.add_argument("--protocol", choices=("tcp", "udp", "best"),
                       help="TCP-like (an exact SOCP) or UDP-like (branch and bound), or best: both for the same "
                            "--alpha, the acknowledgement link priced (--ack-price, --ack-power); required unless "
                            "--target, e.g. --protocol tcp")
    alloc.add_argument("--alpha", help="bound on the optimal expected cost (with --target dp-cost: on the DP law's "
                                       "stationary cost), required unless --target stable or --budget, e.g. --alpha 8")
    alloc.add_argument("--beta", help="price of each channel, comma-separated, required but with power "
                                      "(--power or the file's [power] table), e.g. --beta 1,0.05")
    alloc.add_argument("--bounds", default="0,1", help="lo,hi for every mu_i, e.g. --bounds 0.1,0.99")
    alloc.add_argument("--constraint", action="append", metavar="TEXT",
                       help='a linear constraint (repeatable; default: none), e.g. "mu1 + 2*mu2 <= 1.5" or '
                            '"mu1 >= mu2"')
    alloc.add_argument("--actuator", metavar="zero|hold|buffer[:L][:hold]|all",
                       help="also whether the allocation mu* is stabilisable when the actuator applies zero, holds "
                            "the last input or plays the buffered plan of L inputs on a loss (some law of that "
                            "strategy that the protocol's controller can run, proved exactly, or undecided with the "
                            "reason; with --protocol udp only zero, and hold without noise and with B of full column "
                            "rank); comma-separated, or all (default: none), e.g. --actuator zero,hold")
    alloc.add_argument("--gap", help="relative optimality gap to certify, 1e-9 <= G < 1 (default: 1e-4), e.g. 1e-6")
    alloc.add_argument("--max-boxes", type=int,
                       help="cap on the boxes of the allocation's branch and bound (UDP-like, power, --protocol "
                            "best, and --target, which bisects instead on one channel); at the cap: exit 4 "
                            "(default: 20000), e.g. 100000")
    alloc.add_argument("--time-limit", metavar="SECONDS",
                       help="cap in seconds on the allocation's search (the branch and bound as --max-boxes, and "
                            "--target's one-channel bisection); at the cap: exit 4 (default: none), e.g. 60")
    # design for stability: allocation.stability, cli/allocate_stability.py
    design = alloc.add_argument_group("design for stability (instead of --protocol)")
    design.add_argument("--target", choices=("paper", "attainable", "stable", "dp-cost"),
                        help="the cheapest mu for which some linear law u = -Kx has mean-square radius < RHO "
                             "(stable), or whose DP law's stationary cost is <= --alpha (dp-cost), or (with "
                             "--protocol) whose attainable cost over the horizon is <= --alpha (attainable: TCP-like "
                             "the finite-horizon DP with acknowledgements, behind a chain too); default: paper "
                             "(the paper's J* <= alpha with --protocol), e.g. --target stable")
    design.add_argument("--margin", metavar="RHO",
                        help="with --target stable: the bound RHO on the mean-square radius (the spectral radius of "
                             "the second-moment operator), 0 < RHO <= 1 (default: 1, i.e. stable: radius < 1 - 1e-9), "
                             "e.g. --margin 0.9")
    # transmit power instead of delivery probabilities, and the acknowledgement link priced
    power = alloc.add_argument_group("power-limited links (docs/mathematics.md, Power-limited links)")
    power.add_argument("--power", choices=("exponential", "rayleigh", "table"),
                       help="buy transmit power P per channel: mu = 1 - exp(-P/c), exp(-c/P) or a measured table "
                            "(default: the file's [power] table if --beta is not given), e.g. --power exponential")
    power.add_argument("--power-scale", metavar="C1,C2,..",
                       help="the constant c of each channel (one for all, or m); required with exponential or "
                            "rayleigh unless the file's [power] table has it, e.g. --power-scale 1,2")
    power.add_argument("--power-table", metavar="FILE.csv",
                       help="rows power,mu (or power,mu1,..,mum), powers rising from 0; required with table unless "
                            "the file's [power] table has it, e.g. --power-table link.csv")
    power.add_argument("--budget", metavar="B",
                       help="least J* with total power <= B (instead of --alpha: least power with J* <= alpha; "
                            "default: none), e.g. --budget 3")
    power.add_argument("--power-max", metavar="P1,P2,..",
                       help="a cap on each channel's power (one for all, or m; default: none), e.g. --power-max 5")
    power.add_argument("--ack-price", metavar="C",
                       help="with --protocol best: what the TCP-like design's acknowledgement link costs, in the "
                            "units of beta'mu (default: 0), e.g. --ack-price 0.3")
    power.add_argument("--ack-power", metavar="P",
                       help="with --protocol best and power: the acknowledgement link's transmit power "
                            "(default: 0), e.g. --ack-power 0.5")

    sim = add_command(sub, "simulate", "Monte Carlo of the plans and laws against their exact expectations",
                      examples=["simulate two_actuator --samples 100000 --seed 0",
                                "simulate pendulum --closed-loop --law all --steps 100 --json",
                                "simulate two_actuator --closed-loop --plot loop.png --save runs.npz"])
    mark_system_file(sim.add_argument("file", metavar="FILE", help=FILE_HELP))
    add_system_options(sim)
    sim.add_argument("--samples", type=int, default=10000, help="sampled runs (>= 2), e.g. --samples 100000")
    sim.add_argument("--steps", type=int, default=50, help="closed-loop steps T, e.g. --steps 200")
    sim.add_argument("--seed", type=int, default=0, help="seeds every random stream (>= 0), e.g. --seed 1")
    sim.add_argument("--closed-loop", action="store_true",
                     help="also run the laws u = -K x in closed loop over a stationary channel "
                          "(default: open loop only)")
    sim.add_argument("--law", choices=("tcp", "udp", "dp", "all"), default="all",
                     help="a protocol's receding-horizon law, the DP optimum (closed loop only) or all, e.g. --law dp")
    sim.add_argument("--actuator", metavar="zero|hold|buffer[:L][:hold]|all",
                     help="with --closed-loop: each law's loop when the actuator applies zero, holds the last input "
                          "or plays the buffered plan of L inputs (default L: the horizon; :hold holds once it is "
                          "exhausted) on a loss, sampled beside its exact cost and radius; with a [constraints] "
                          "table: the constrained loop under each strategy, on the same paths; comma-separated, or "
                          "all (default: none), e.g. --actuator hold")
    sim.add_argument("--mpc-samples", type=int, metavar="K",
                     help="with a [constraints] table in FILE: runs of the constrained receding-horizon loop (each "
                          "re-solves its program every step: about 5 ms a solve), the clipped law, certainty-"
                          "equivalent and expected-cost MPC on the same paths over --steps steps; 0 skips it "
                          "(default: 100), e.g. --mpc-samples 400")
    add_constraint_options(sim, "the constrained receding-horizon loop's programs")
    sim.add_argument("--threads", type=int, default=1, metavar="T",
                     help="threads running the constrained loop's runs, each with its own compiled programs; the "
                          "answer is the serial one, float for float (default: 1), e.g. --threads 2")
    add_dask_options(sim, "the constrained loop's runs as Dask tasks (the answer is the serial one, float for float)")
    sim.add_argument("--save", metavar="FILE.npz",
                     help="save closed-loop trajectories (first 1000 runs) and curves (default: none), "
                          "e.g. --save runs.npz")
    sim.add_argument("--plot", metavar="FILE",
                     help="figure of the closed loop: mean +- band of ||x_t||, cost (default: none), "
                          "e.g. --plot loop.png")
    sim.add_argument("--yscale", choices=("linear", "log", "symlog"),
                     help="with --plot: the y axes' scale (default: linear); log (or symlog) keeps a diverging law "
                          "from flattening the others, e.g. --yscale log")
    add_figure_options(sim, "the --plot figure")

    swp = add_command(sub, "sweep", "J*_tcp, J*_udp and J_Delta over a grid of channels, x0 scales or horizons",
                      examples=["sweep two_actuator --mu-grid 201 --out sweep-out",
                                "sweep pendulum --x0-scales 0:2:5 --json",
                                "sweep two_actuator --mu-grid 201 --dask local --out sweep-out --netcdf"],
                      results=False)
    mark_system_file(swp.add_argument("file", metavar="FILE", help=FILE_HELP))
    swp.add_argument("--protocol", choices=("tcp", "udp", "both"), default="both",
                     help="TCP-like, UDP-like or both (then also J_Delta), e.g. --protocol udp")
    what = swp.add_argument_group("what to sweep (exactly one)").add_mutually_exclusive_group(required=True)
    what.add_argument("--mu-grid", type=int, metavar="K",
                      help="K points per channel on [0, 1]: 1-D for one channel, 2-D for two (required: this or "
                           "one of the four below), e.g. --mu-grid 201")
    what.add_argument("--mu-list", metavar="FILE.csv",
                      help="m-channel points, one row each, a header row skipped (required: one of five), "
                           "e.g. --mu-list points.csv")
    what.add_argument("--x0-scales", metavar="S1,S2,..|LO:HI:K",
                      help="x0 times each scale, or K scales from LO to HI (required: one of five), "
                           "e.g. --x0-scales 0:2:21")
    what.add_argument("--horizons", metavar="N1,N2,..",
                      help="each horizon N (required: one of five), e.g. --horizons 5,10,20,40")
    what.add_argument("--burstiness", metavar="L1,L2,..|LO:HI:K",
                      help="Gilbert channels with the file's average rates and burstiness lambda = 1 - p - r: "
                           "plug-in laws against the exact minimum under correlated losses (required: one of five), "
                           "e.g. --burstiness 0:0.9:10")
    swp.add_argument("--mean-rate", metavar="M1,M2,..|LO:HI:K",
                     help="with --burstiness: a map over channel I's (--channel, default 1) mean delivery rate and "
                          "lambda, the other channels as in the file (default: none), e.g. --mean-rate 0.5:1:11")
    swp.add_argument("--channel", type=int, metavar="I",
                     help="with --mu-grid: sweep channel I only, the others as in the file (default: all channels "
                          "for m <= 2); with --mean-rate: the mapped channel (default: 1), e.g. --channel 2")
    swp.add_argument("--shared", action="store_true", help="with --mu-grid: every actuator behind one channel nu")
    swp.add_argument("--chunk-size", type=int, default=2048, metavar="C",
                     help="points per batched evaluation and per Dask task, e.g. --chunk-size 10000")
    add_dask_options(swp, "evaluate on Dask")
    swp.add_argument("--out", metavar="DIR",
                     help="a folder: sweep.npz, sweep.csv and the figures (sweep.png; for a 2-D grid sweep_tcp.png, "
                          "sweep_udp.png, sweep_diff.png; with --stability stability.png; in --format) "
                          "(default: none), e.g. --out sweep-out")
    swp.add_argument("--netcdf", action="store_true", help="also write DIR/sweep.nc (needs the xarray extra)")
    swp.add_argument("--stability", action="store_true",
                     help="also each law's mean-square spectral radius in closed loop (radius_tcp, radius_udp)")
    add_figure_options(swp, "the figures in --out")
    swp.add_argument("--json", action="store_true", help="print one JSON object on stdout instead of text")

    reg = add_command(sub, "region", "can the loop be stabilised over these links: each law's critical mu and map",
                      examples=["region two_actuator --json", "region pendulum --law dp",
                                "region two_actuator --grid 51 --channels 1,2 --out region-out"], results=False)
    reg.add_argument("file", metavar="FILE", help=FILE_HELP)
    add_system_options(reg, schedule=False)     # the loop runs for ever over one channel
    reg.add_argument("--law", choices=("dp", "tcp", "udp", "fixed", "all"), default="all",
                     help="dp (some linear law: the stabilisable set), the paper's tcp / udp laws re-designed at "
                          "each mu, fixed (the DP gain at the file's mu), or all, e.g. --law dp")
    reg.add_argument("--direction", metavar="D1,..,Dm",
                     help="the ray mu = t * direction, nonnegative (default: all ones; behind a Gilbert-Elliott chain "
                          "the ray of mean rates, burstiness kept), e.g. --direction 1,0.5")
    reg.add_argument("--grid", type=int, metavar="K",
                     help="also a K x K map of two channels on [0, 1], the others at the file's mu (default: none), "
                          "e.g. --grid 51")
    reg.add_argument("--channels", metavar="I,J", help="with --grid: the map's channels (default: 1,2), e.g. "
                                                         "--channels 1,3")
    add_dask_options(reg, "with --grid: the map's rows on Dask")
    reg.add_argument("--sensor-grid", type=int, metavar="K",   # lossy sensor links
                     help="a file with [sensor]: also a K x K map of (gamma, mu) scales in (0, 1] for the paper's "
                          "tcp and udp laws on their estimates (default: none), e.g. --sensor-grid 11")
    reg.add_argument("--actuator", metavar="zero|hold|buffer[:L][:hold]|all",
                     help="also each strategy on a loss (apply zero, hold the last input, play the buffered plan of "
                          "L inputs): the critical mu along the ray of some TCP-like law of that strategy, its upper "
                          "end proved stable; comma-separated, or all (default: none), e.g. --actuator zero,hold")
    reg.add_argument("--out", metavar="DIR",
                     help="a folder: region.npz, region.csv and (with --grid) region.png (in --format) "
                          "(default: none), e.g. --out region-out")
    add_figure_options(reg, "the figures in --out")
    reg.add_argument("--json", action="store_true", help="print one JSON object on stdout instead of text")

    cmp = add_command(sub, "compare", "the actuator strategies on a loss side by side: zero, hold, buffered plan",
                      examples=["compare two_actuator", "compare pendulum --actuator zero,hold,buffer:3 --json",
                                "compare two_actuator --actuator zero,hold --target 8 --beta 1,0.5"])
    cmp.add_argument("file", metavar="FILE", help=FILE_HELP)
    add_system_options(cmp, schedule=False)     # the loop runs for ever over one channel
    cmp.add_argument("--actuator", metavar="zero|hold|buffer[:L][:hold]|all", default="all",
                     help="the strategies: apply zero, hold the last input, or play the buffered plan of L inputs "
                          "(default L: the horizon); comma-separated, or all (default: all), e.g. --actuator "
                          "zero,buffer:2")
    cmp.add_argument("--direction", metavar="D1,..,Dm",
                     help="the ray mu = t * direction of the critical mu, nonnegative (default: all ones), e.g. "
                          "--direction 1,0.5")
    cmp.add_argument("--target", metavar="J",
                     help="also the cheapest links (min beta'mu) at which each strategy's optimal TCP-like law costs "
                          "at most J (its average stage cost with process noise, else its noise-free cost from x0), "
                          "or unreachable with the least cost (default: none), e.g. --target 8")
    cmp.add_argument("--beta", metavar="B1,..,Bm",
                     help="with --target: the price of each channel's delivery probability (default: all ones), "
                          "e.g. --beta 1,0.05")
    cmp.add_argument("--gap", help="with --target: relative optimality gap to certify, 1e-9 <= G < 1 (default: 1e-4), "
                                   "e.g. 1e-6")
    cmp.add_argument("--protocol", choices=["tcp", "udp"], default="tcp",
                     help="the controller's information: tcp (acknowledged, default) or udp (no acknowledgements: a "
                          "strategy whose optimal law it cannot run gets its row's reason instead; named with "
                          "--actuator, it is refused), e.g. --protocol udp")

    rep = add_command(sub, "reproduce", "every figure and table of the paper, with a report comparing them",
                      examples=["reproduce", "reproduce --out paper-results", "reproduce --quick --out smoke"],
                      results=False)
    rep.add_argument("--out", metavar="DIR", default="results",
                     help="a folder: one figure per paper figure (in --format), results.json, report.md, claims.md "
                          "and manifest.json, e.g. --out paper-results")
    rep.add_argument("--quick", action="store_true", help="coarse grids, one alpha, a shorter audit (a smoke test)")
    add_figure_options(rep, "the figures")
    rep.add_argument("--json", action="store_true", help="print one JSON object on stdout instead of text")
    return parser


def join_negative_values(argv: list[str]) -> list[str]:
    """``--x0 -1,1`` -> ``--x0=-1,1``: argparse would read ``-1,1`` as an unknown option.

    Examples
    --------
    >>> join_negative_values(["solve", "pendulum", "--x0", "-1,1"])
    ['solve', 'pendulum', '--x0=-1,1']
    """
    out: list[str] = []
    k = 0
    while k < len(argv):
        if argv[k] in NUMBER_LISTS and k + 1 < len(argv) and re.match(r"-[\d.]", argv[k + 1]):
            out.append(f"{argv[k]}={argv[k + 1]}")
            k += 2
        else:
            out.append(argv[k])
            k += 1
    return out
