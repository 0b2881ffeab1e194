"""``packetloss-cvx reproduce [--out DIR]``: every figure and table of the paper from the packaged
examples, with ``results.json`` and ``report.md`` saying, figure by figure, what matches the paper.

Deterministic (no clock, no unseeded randomness in any file written, but for the time in manifest.json). Steps: the
pendulum's costs
over nu, the two-actuator grids, the allocations of §VI for both protocols, Tables I–II, the
two-actuator system's stability region of each law (beyond the paper), the audit, the figures, the report.
"""

from __future__ import annotations

import argparse
import contextlib
import time
from pathlib import Path
from typing import Any

import numpy as np

from ..allocation.ack import attainable_break_even, break_even_of
from ..allocation.attainable import tcp_attainable_cost
from ..claims import CLAIMS, audit, claims_document, tally, tally_text
from ..claims.paper import ALLOCATION_BETAS, TABLE_1, TABLE_1_MU, TABLE_2, TABLE_2_MU
from ..display import json_text
from ..model.files import load_example
from ..plots import plot_ack_break_even, plot_cost_lines, plot_log_contour, plot_region, plot_strategy_map
from ..progress import progress_bar
from ..runfolder import RunFolder
from ..safeio import save_figure
from ..studies import paper_figures as pf
from ..studies.actuator_map import strategy_map
from ..studies.region_map import region_map
from ..threads import blas_limited
from .common import CommandResult, figure_dpi
from .reproduce_report import ACK_FIGURE, CLAIMS_FILE, FIGURES, REGION_FIGURE, REGION_LAWS, STRATEGY_FIGURE, report

#: compute and draw_figures (run's two steps) are not exported: benchmarks/reproduce_speed.py calls them
__all__ = ["ACK_ATTAINABLE_ALPHAS", "ACK_ATTAINABLE_GAP", "ALPHAS", "BASIS_LABELS", "REGION_GRID", "SETTINGS",
           "SLOW_CLAIM", "STEPS", "TITLES", "WRITE_STEPS", "run"]

#: The cost bounds alpha of the -mult figures: the paper's 4.78 among levels spread from just above
#: J*(1, 1) = 1.92 to below J*(0, 0) = 140.7 of the two-actuator system (the paper prints none). Above 20
#: the UDP-like branch and bound takes about 1 s per alpha (three betas).
ALPHAS = (2.5, 3.5, 4.78, 6.0, 8.0, 12.0, 20.0, 35.0, 50.0, 70.0, 100.0)

#: The alphas at which the acknowledgement price is also computed on the attainable basis (the TCP-like design on
#: the finite-horizon DP's cost, beta = (1, 1)), and the relative gap those designs are certified to: each is a
#: branch and bound without a TCP-like floor, 0.1-0.3 s CPU at this gap (1-3 s at 1e-4, where the designs move by
#: under 3e-6 relative), so four of the ALPHAS keep the run within its budget (docs/performance.md).
ACK_ATTAINABLE_ALPHAS = (4.78, 8.0, 20.0, 50.0)
ACK_ATTAINABLE_GAP = 1e-2

#: what each protocol's J* on the maps is (docs/design.md, "Cost bases"): J*_tcp the paper's first-moment value,
#: which no law attains; J*_udp the exact expected cost of its plan, the paper's and the attainable cost at once
BASIS_LABELS = {"tcp": "paper basis", "udp": "paper = attainable basis"}

#: The claim --quick leaves out of the audit (its 18 brute-force allocations, about 0.5 s).
SLOW_CLAIM = "allocation-udp-perfect-channel"

#: The region map's K x K grid over (mu1, mu2) of the two-actuator system: the coarsest grid
#: whose boundaries stay within half a step (0.025) of the 101 x 101 map's, and on which the DP law's boundary
#: near the axes (S reaches mu1 = 0 at mu2 = 0.115) spans more than two steps. CPU s for dp, tcp, udp, the
#: eigenpairs batched (docs/performance.md): K = 11 0.4, 16 0.5, 21 0.6, 31 1.1, 41 2.0.
REGION_GRID = 21

#: Sizes of the full run and of ``--quick`` (a smoke test: coarse grids, one alpha, the audit on the paper's
#: systems only and without SLOW_CLAIM). The full run's audit is docs/claims.md's (``audit --random 200
#: --seed 1``), so its claims.md is the project's, case for case.
SETTINGS = {
    "full": {"grid": 101, "nu_points": 150, "alphas": ALPHAS, "audit_random": 200, "audit_seed": 1,
             "audit_skips": (), "region_grid": REGION_GRID, "strategy_grid": 6},
    "quick": {"grid": 21, "nu_points": 30, "alphas": (4.78,), "audit_random": 0, "audit_seed": 1,
              "audit_skips": (SLOW_CLAIM,), "region_grid": 6, "strategy_grid": 2},
}


#: Each figure's title, in words with the paper's symbols (the paper's label names the file, not the title).
TITLES = {
    "fig:log-cost-pendulum": r"Inverted pendulum, one shared channel: expected cost of both protocols and "
                             r"$J_\Delta$ against the delivery probability $\nu$",
    "fig:cost-diff-mixed": r"Two-actuator system: the price of losing acknowledgements, "
                           r"$J_\Delta = J^*_{\mathrm{udp}} - J^*_{\mathrm{tcp}}$",
    "fig:TCP-log-cost-mixed": r"Two-actuator system, TCP-like protocol: the optimal cost "
                              r"$J^*_{\mathrm{tcp}}(\mu_1, \mu_2)$",
    "fig:UDP-log-cost-mixed": r"Two-actuator system, UDP-like protocol: the optimal cost "
                              r"$J^*_{\mathrm{udp}}(\mu_1, \mu_2)$",
    "fig:TCP-log-cost-mixed-mult": "TCP-like protocol: the cheapest delivery rates on each cost contour\n"
                                   r"$\min\ \beta^\top\mu$ subject to $J^*_{\mathrm{tcp}}(\mu) \leq \alpha$, "
                                   r"one path per price vector $\beta$",
    "fig:UDP-log-cost-mixed-mult": "UDP-like protocol: the cheapest delivery rates on each cost contour\n"
                                   r"$\min\ \beta^\top\mu$ subject to $J^*_{\mathrm{udp}}(\mu) \leq \alpha$, "
                                   r"one path per price vector $\beta$",
    ACK_FIGURE: r"Two-actuator system, $\beta = (1, 1)$: the acknowledgement price at which UDP-like wins",
    REGION_FIGURE: r"Two-actuator system: where each law stabilises the loop in mean square, over $(\mu_1, \mu_2)$",
    STRATEGY_FIGURE: r"Two-actuator system: the cheapest actuator strategy on a lost packet, over $(\mu_1, \mu_2)$",
}


def _beta(beta: Any) -> tuple[float, ...]:
    """A price vector as a tuple: ``compute``'s key, or results.json's text of it (``"1.0, 0.05"``)."""
    return tuple(float(b) for b in (beta.split(",") if isinstance(beta, str) else beta))


def _beta_text(beta: Any) -> str:
    """A price vector as the legend writes it: ``(1.0, 0.05)`` (or ``"1.0, 0.05"``) -> ``$\\beta = (1, 0.05)$``."""
    return r"$\beta = (" + ", ".join(f"{b:g}" for b in _beta(beta)) + ")$"


#: compute's steps, in order; run adds WRITE_STEPS to the same progress bar
STEPS = ("pendulum", "grids", "allocations tcp", "allocations udp", "tables", "region", "strategies", "audit")
#: run's steps after compute: the figures drawn and saved, then claims.md, results.json and report.md
WRITE_STEPS = ("figures", "report")


@blas_limited      # the maximisers, tables and audit loops of small dense algebra (threads.py)
def compute(settings: dict[str, Any], progress: bool | None, seconds: dict[str, float],
            bar: Any = None) -> dict[str, Any]:
    """The data of every figure, table and the audit for ``settings`` (one of `SETTINGS`), each step's wall
    seconds put in ``seconds``; nothing is written. Called by `run` (and by benchmarks/reproduce_speed.py).
    ``bar``: a progress bar (progress.progress_bar) that the steps advance, the caller's; None: its own."""
    pendulum, mixed = load_example("pendulum"), load_example("two_actuator")
    data: dict[str, Any] = {"settings": {k: list(v) if isinstance(v, tuple) else v for k, v in settings.items()}}
    with contextlib.nullcontext(bar) if bar is not None else progress_bar(total=len(STEPS), desc="reproduce",
                                                                          progress=progress) as bar:
        for step in STEPS:
            bar.set_postfix_str(step)
            start = time.perf_counter()
            if step == "pendulum":
                data["pendulum"] = pf.log_cost_pendulum(pendulum, settings["nu_points"])
            elif step == "grids":
                data["mixed"] = pf.mixed_grids(mixed, settings["grid"])
            elif step.startswith("allocations"):
                protocol = step.split()[1]
                data.setdefault("allocations", {})[protocol] = pf.mixed_allocations(
                    mixed, protocol, settings["alphas"], ALLOCATION_BETAS, progress=progress)

            elif step == "region":   # beyond the paper: each law's stability region
                data["region"] = region_map(mixed, laws=REGION_LAWS, grid=settings["region_grid"]).to_dict()
            elif step == "strategies":   # beyond the paper: which actuator strategy on a loss wins where
                data["strategies"] = strategy_map(mixed, settings["strategy_grid"]).to_dict()
            elif step == "tables":
                data["tables"] = pf.eigenvalue_tables(pendulum, mixed, TABLE_1_MU, TABLE_2_MU)
                data["tables_paper"] = {"table-1": TABLE_1, "table-2": TABLE_2}
            else:
                # the acknowledgement link's break-even price, from the allocations above (no solve)
                data["ack"] = {str(list(beta)): break_even_of(data["allocations"]["tcp"][beta],
                                                              data["allocations"]["udp"][beta])
                               for beta in data["allocations"]["tcp"]}
                # and on the attainable basis, beta = (1, 1): the TCP-like design on the finite-horizon DP's cost
                data["ack_attainable"] = attainable_break_even(
                    mixed, [a for a in ACK_ATTAINABLE_ALPHAS if a in settings["alphas"]], (1.0, 1.0),
                    data["allocations"]["udp"][(1.0, 1.0)], gap=ACK_ATTAINABLE_GAP)
                data["ack_attainable"]["gap"] = ACK_ATTAINABLE_GAP
                paper = {row["alpha"]: row["mu"] for row in data["allocations"]["tcp"][(1.0, 1.0)]}
                data["ack_attainable"]["paper_design_attains"] = [      # what the paper-basis design's loop costs
                    None if paper[a] is None else tcp_attainable_cost(mixed, np.asarray(paper[a]))
                    for a in data["ack_attainable"]["alpha"]]
                only = [c for c in CLAIMS if c not in settings["audit_skips"]]
                data["audit"] = audit(random=settings["audit_random"], seed=settings["audit_seed"], only=only,
                                      progress=progress)
            seconds[step] = time.perf_counter() - start
            bar.update()
    return data


def draw_figures(data: dict[str, Any], folder: RunFolder, fmt: str = "png", dpi: float | None = None
                 ) -> dict[str, Path]:
    """Every figure of `compute`'s ``data`` saved into ``folder`` in format ``fmt`` at ``dpi`` (default
    safeio.FIGURE_DPI): ``{label: path}``. Called by `run` (and by benchmarks/reproduce_speed.py)."""
    out = folder.path
    paths = {label: out / f"{label.removeprefix('fig:')}.{fmt}" for label in FIGURES}
    pend, mixed = data["pendulum"], data["mixed"]
    caption = TITLES
    draw = {}
    draw["fig:log-cost-pendulum"] = plot_cost_lines(pend["nu"], {key: pend[key] for key in ("tcp", "udp", "diff")},
                    xlabel=r"delivery probability $\nu$ (shared channel; log scale)", xscale="log",
                    marker=pend["maximiser"]["nu"],
                    marker_label=rf"max $J_\Delta$ at $\nu$ = {pend['maximiser']['nu']:.3g}",
                    title=caption["fig:log-cost-pendulum"])
    axis = mixed["axis"]
    draw["fig:cost-diff-mixed"] = plot_log_contour(axis, axis, mixed["diff"],
                                                   colorbar_label=r"$J_\Delta$ (log scale)",
                                                   marker=mixed["maximiser"]["mu"],
                                                   title=caption["fig:cost-diff-mixed"])
    both = data.get("ack_attainable")
    for protocol in ("tcp", "udp"):
        name = protocol.upper()
        basis = BASIS_LABELS[protocol]
        draw[f"fig:{name}-log-cost-mixed"] = plot_log_contour(
            axis, axis, mixed[protocol], colorbar_label=rf"$J^*_{{\mathrm{{{protocol}}}}}$, {basis} (log scale)",
            title=caption[f"fig:{name}-log-cost-mixed"])
        lines = {_beta_text(beta) + (", paper" if protocol == "tcp" else ""): [row["mu"] for row in rows]
                 for beta, rows in data["allocations"][protocol].items()}
        # where each path of optima jumps (its line is broken there), read on the cost grid: milliseconds
        breaks = {_beta_text(beta) + (", paper" if protocol == "tcp" else ""):
                  pf.path_jumps(axis, mixed[protocol], _beta(beta), data["settings"]["alphas"])
                  for beta in data["allocations"][protocol]}
        if protocol == "tcp" and both and any(mu is not None for mu in both.get("mu", [])):
            # beyond the paper: the TCP-like designs on the cost a loop attains, where they differ from the paper's
            lines[_beta_text((1.0, 1.0)) + ", attainable"] = both["mu"]
        draw[f"fig:{name}-log-cost-mixed-mult"] = plot_log_contour(
            axis, axis, mixed[protocol], colorbar_label=rf"$J^*_{{\mathrm{{{protocol}}}}}$, {basis} (log scale)",
            levels=data["settings"]["alphas"], allocations=lines, breaks=breaks,
            title=caption[f"fig:{name}-log-cost-mixed-mult"])
    for label, figure in draw.items():
        save_figure(figure, paths[label].name, folder=folder, dpi=dpi)
    ack = data["ack"][str([1.0, 1.0])]         # beyond the paper: the acknowledgement link priced
    paths[ACK_FIGURE] = out / f"{ACK_FIGURE}.{fmt}"
    save_figure(plot_ack_break_even(ack["alpha"], [float("nan") if v is None else v for v in ack["break_even"]],
                                    title=TITLES[ACK_FIGURE],
                                    attainable=None if not both or not both["alpha"] else (
                                        both["alpha"], [float("nan") if v is None else v for v in both["break_even"]])),
                paths[ACK_FIGURE].name, folder=folder, dpi=dpi)
    grid = {law: data["region"][law]["grid"] for law in REGION_LAWS}     # beyond the paper
    paths[REGION_FIGURE] = out / f"{REGION_FIGURE}.{fmt}"
    save_figure(plot_region(grid["dp"]["axis"], {law: _numbers(g["radius"]) for law, g in grid.items()},
                            {law: _numbers(g["stable"]) for law, g in grid.items()},
                            title=TITLES[REGION_FIGURE]),
                paths[REGION_FIGURE].name, folder=folder, dpi=dpi)
    found = data["strategies"]                                           # beyond the paper
    paths[STRATEGY_FIGURE] = out / f"{STRATEGY_FIGURE}.{fmt}"
    save_figure(plot_strategy_map(found["axis"], found["strategies"], found["winner"],
                                  title=TITLES[STRATEGY_FIGURE]),
                paths[STRATEGY_FIGURE].name, folder=folder, dpi=dpi)
    return paths


def _numbers(rows: list) -> list:
    """A RegionMap.to_dict() grid (None where undecided or not finite) as numbers, nan for None."""
    return [[float("nan") if v is None else float(v) for v in row] for row in rows]


def run(args: argparse.Namespace) -> CommandResult:
    """Compute, draw, and write ``results.json`` and ``report.md`` into ``--out``.

    Examples
    --------
    The run takes seconds even with ``--quick``; a folder it cannot use is refused before any work:

    >>> import tempfile
    >>> from packetloss_cvx.cli.parser import build_parser
    >>> from packetloss_cvx.errors import InputError
    >>> run(build_parser().parse_args(["reproduce", "--out", " "]))        # an unset $DIR
    Traceback (most recent call last):
        ...
    packetloss_cvx.errors.InputError: --out: expected a folder, found an empty path
    >>> with tempfile.NamedTemporaryFile() as file:                          # a file, not a folder
    ...     try:
    ...         run(build_parser().parse_args(["reproduce", "--quick", "--out", file.name]))
    ...     except InputError as err:
    ...         print(err.field, "not a folder" in err.detail)
    --out True
    """
    settings = SETTINGS["quick" if args.quick else "full"]
    progress = False if args.quiet else None
    with RunFolder(args.out, command=getattr(args, "command_line", "packetloss-cvx reproduce"),
                   force=getattr(args, "force", False), field="--out") as folder:    # before any work
        seconds: dict[str, float] = {}      # printed, never written: the files stay deterministic
        with progress_bar(total=len(STEPS) + len(WRITE_STEPS), desc="reproduce", progress=progress) as bar:
            data = compute(settings, progress, seconds, bar=bar)
            bar.set_postfix_str("figures")
            start = time.perf_counter()
            figures = draw_figures(data, folder, getattr(args, "format", None) or "png", figure_dpi(args))
            seconds["figures"] = time.perf_counter() - start
            bar.update()
            bar.set_postfix_str("report")
            start = time.perf_counter()
            command = f"packetloss-cvx audit --random {settings['audit_random']} --seed {settings['audit_seed']}"
            if settings["audit_skips"]:
                command += f"` without {', '.join(settings['audit_skips'])}, as `reproduce --quick"
            with folder.write(CLAIMS_FILE, text=True) as handle:
                handle.write(claims_document(data["audit"], command))
            out = folder.path
            text, verdicts = report(data, figures, out)
            results = {key: value for key, value in data.items() if key != "audit"}
            results["audit"] = [r.to_dict() for r in data["audit"]]
            results["audit_tally"] = tally(data["audit"])
            results["figures"] = {label: path.name for label, path in figures.items()}
            results["verdicts"] = verdicts
            with folder.write("results.json", text=True) as handle:
                handle.write(json_text(results, indent=1) + "\n")
            with folder.write("report.md", text=True) as handle:
                handle.write(text)
            seconds["report"] = time.perf_counter() - start
            bar.update()
    files = [*(p.name for p in figures.values()), "results.json", "report.md", CLAIMS_FILE]
    lines = [f"reproduce: wrote {len(files)} files in {out}",
             f"  audit: {tally_text(data['audit'])} (details in {out / CLAIMS_FILE})"]
    lines += [f"  {label}: {verdict}" for label, verdict in verdicts.items()]
    lines.append("  seconds: " + ", ".join(f"{k} {v:.1f}" for k, v in seconds.items()))
    lines.append(f"  read {out / 'report.md'}")
    return CommandResult({"out": str(out), "files": files, "audit": tally(data["audit"]), "verdicts": verdicts,
                          "seconds": seconds}, "\n".join(lines))
