"""``packetloss-cvx sweep FILE``: `J*_tcp`, `J*_udp` and J_Delta over a design study, saved with a figure."""

from __future__ import annotations

import argparse
import contextlib
from pathlib import Path
from typing import Any

import numpy as np

from ..closedloop.stability import is_mean_square_stable
from ..errors import InputError
from ..model.files import load_system
from ..model.system import System
from ..model.validation import channel_range
from ..results import BurstinessMap, BurstinessSweep, DesignSweep, plugin_loss
from ..runfolder import RunFolder
from ..safeio import save_figure
from ..studies import read_mu_list, require_xarray, sweep
from ..studies.burstiness import burstiness_map, burstiness_sweep
from ..studies.engine import DEFAULT_CHUNK
from ..studies.output import csv_header, csv_number, sweep_table, write_sweep
from ..tolerances import SELF_CHECK_RTOL
from . import format as fmt
from .common import (
    CHAIN_BASIS,
    COST_BASIS,
    CommandResult,
    check_dead_flags,
    figure_dpi,
    figure_file,
    integers,
    number_range,
)

__all__ = ["bursty", "bursty_map", "run"]

#: the API's argument names -> the flags that set them (errors are renamed to the flag)
FLAGS = {"mu_grid": "--mu-grid", "mu_list": "--mu-list", "x0_scales": "--x0-scales", "horizons": "--horizons",
         "channel": "--channel", "chunk_size": "--chunk-size", "dask": "--dask", "workers": "--workers",
         "out": "--out", "shared": "--shared", "netcdf": "--netcdf"}

#: ``sweep --json`` carries every point up to this many (a 2-D grid of 223 x 223; about 4.4 MB of JSON for
#: two channels); above it, the JSON names the file that holds them (``--out DIR``: DIR/sweep.csv)
JSON_MAX_POINTS = 50_000

#: the sweep's kind in the figures' titles
_KINDS = {"mu-grid": "grid of delivery probabilities", "mu-list": "list of delivery probabilities",
          "x0-scale": "range of initial-state scales", "horizon": "range of horizons"}
_AXIS_LABELS = {"nu": r"shared channel $\nu$", "x0_scale": r"scale $s$ of $x_0$ ($s\,x_0$)",
                "horizon": "horizon $N$", "point": "point (row of --mu-list)"}


def _options(args: argparse.Namespace, m: int) -> dict[str, Any]:
    options: dict[str, Any] = {}
    if args.mu_grid is not None:
        options["mu_grid"] = args.mu_grid
    elif args.mu_list is not None:
        options["mu_list"] = read_mu_list(args.mu_list, m)
    elif args.x0_scales is not None:
        options["x0_scales"] = number_range(args.x0_scales, "--x0-scales")
    else:
        options["horizons"] = integers(args.horizons, "--horizons")
    if args.channel is not None:
        if not 1 <= args.channel <= m:
            raise InputError("--channel", f"expected {channel_range(m, True)}, found {args.channel}")
        options["channel"] = args.channel - 1
    return options


def _figures(result: DesignSweep, out: RunFolder, skipped: list[str], args: argparse.Namespace) -> list[Path]:
    """The sweep's figures in the folder ``out``; a log contour with no positive value to draw (e.g. every cost 0
    at x0 = 0 without noise) is not drawn, and its name goes to ``skipped``. With ``--stability`` also each law's
    mean-square radius (`_stability_figures`)."""
    from ..plots import plot_cost_lines, plot_log_contour  # matplotlib (0.2-0.7 s) only where a figure is asked for
    curves = {**result.costs, **({"diff": result.difference} if result.difference is not None else {})}
    title = f"{result.name or 'system'}: expected cost over a {_KINDS.get(result.kind, result.kind)}"
    stability = _stability_figures(result, out, skipped, args) if result.radii else []
    if len(result.dims) == 1:
        dim = result.dims[0]
        label = _AXIS_LABELS.get(dim, rf"$\mu_{dim[2:]}$" if dim.startswith("mu") else dim)
        figure = plot_cost_lines(result.axes[0], curves, xlabel=label, title=title)
        return [save_figure(figure, figure_file(args, "sweep"), folder=out, dpi=figure_dpi(args)), *stability]
    paths = []
    names = {"tcp": r"$J^*_{\mathrm{tcp}}$, paper basis", "udp": r"$J^*_{\mathrm{udp}}$, paper = attainable basis",
             "diff": r"$J_\Delta = J^*_{\mathrm{udp}} - J^*_{\mathrm{tcp}}$, paper basis"}
    for key, values in curves.items():
        if not np.any(np.asarray(values) > 0):
            skipped.append(figure_file(args, f"sweep_{key}"))
            continue
        figure = plot_log_contour(result.axes[1], result.axes[0], np.asarray(values).reshape(result.shape),
                                  colorbar_label=f"{names[key]} (log scale)", title=f"{title}: {names[key]}")
        paths.append(save_figure(figure, figure_file(args, f"sweep_{key}"), folder=out, dpi=figure_dpi(args)))
    return [*paths, *stability]


def _stability_figures(result: DesignSweep, out: RunFolder, skipped: list[str], args: argparse.Namespace
                       ) -> list[Path]:
    """``--stability``'s figures: for a 1-D sweep stability.png (each law's mean-square radius against the swept
    quantity, radius 1 marked); for a square 2-D grid stability_<protocol>.png (the law's radius over (mu1, mu2)
    with its radius = 1 boundary, plots.plot_region); other shapes go to ``skipped``."""
    from ..plots import plot_region, plot_stability_lines  # matplotlib only where a figure is asked for
    title = f"{result.name or 'system'}: mean-square stability of each law in closed loop"
    if len(result.dims) == 1:
        dim = result.dims[0]
        label = _AXIS_LABELS.get(dim, rf"$\mu_{dim[2:]}$" if dim.startswith("mu") else dim)
        figure = plot_stability_lines(result.axes[0], dict(result.radii), xlabel=label, title=title)
        return [save_figure(figure, figure_file(args, "stability"), folder=out, dpi=figure_dpi(args))]
    if len(result.dims) != 2 or not np.array_equal(result.axes[0], result.axes[1]):
        skipped.extend(figure_file(args, f"stability_{p}") for p in result.radii)
        return []
    paths = []
    for p, radii in result.radii.items():
        grid = np.asarray(radii, dtype=float).reshape(result.shape)
        stable = np.array([float(is_mean_square_stable(r)) for r in grid.ravel()]).reshape(result.shape)
        figure = plot_region(result.axes[1], {p: grid}, {p: stable}, xlabel=r"$\mu_1$", ylabel=r"$\mu_2$",
                             radius_label=f"mean-square radius of the {p.upper()}-like law",
                             title=f"{title}: {p.upper()}-like")
        paths.append(save_figure(figure, figure_file(args, f"stability_{p}"), folder=out, dpi=figure_dpi(args)))
    return paths


def _summary(result: DesignSweep) -> tuple[dict[str, Any], list[str]]:
    data: dict[str, Any] = {"name": result.name, "kind": result.kind, "dims": list(result.dims),
                            "shape": list(result.shape), "points": int(result.mu.shape[0])}
    points = f"{data['points']} point{'s' if data['points'] != 1 else ''}"
    lines = [f"{fmt.name(result.name or 'system')}: {result.kind} sweep, {points} "
             f"({' x '.join(map(str, result.shape))} over {', '.join(result.dims)})"]
    columns = {**result.costs, **({"diff": result.difference} if result.difference is not None else {})}
    for key, values in columns.items():
        k = int(np.argmax(values))
        where = {d: a[i].item() for d, a, i in zip(result.dims, result.axes, np.unravel_index(k, result.shape),
                                                   strict=True)}
        data[f"cost_{key}"] = {"min": float(np.min(values)), "max": float(np.max(values)), "argmax": where,
                               "argmax_mu": result.mu[k].tolist()}
        name = ("J_Delta" if key == "diff" else f"J*_{key}") + f" ({COST_BASIS[key]} basis)"
        data.setdefault("basis", {})[f"cost_{key}"] = "paper"
        at = ", ".join(f"{d} = {v:.6g}" for d, v in where.items())
        lines.append(f"  {name}: min {np.min(values):.6g}, max {np.max(values):.6g} at {at}")
    for p, radii in result.radii.items():
        radii = np.asarray(radii, dtype=float)
        stable = int(sum(is_mean_square_stable(r) for r in radii))
        known = radii[np.isfinite(radii)]
        low, high = (float(known.min()), float(known.max())) if known.size else (None, None)
        data[f"radius_{p}"] = {"min": low, "max": high, "stable_points": stable}
        span = f"{low:.4g} to {high:.4g}" if known.size else "not computed"
        text = f"  {p.upper()}-like law in closed loop: mean-square radius {span}; proved stable at {stable} of " \
               f"{radii.size} points"
        if known.size < radii.size:
            missing = radii.size - known.size
            reason = (f"the radius was not computed at {missing} of {radii.size} points (null in the table): a "
                      "numerical failure in double precision, the law's second-moment map overflowing or its "
                      "eigenvalues not found; those points are not proved stable")
            data[f"radius_{p}"].update(missing_points=missing, reason=reason)
            text += f" ({reason})"
        lines.append(text)
    return data, lines


def _points(result: DesignSweep, data: dict[str, Any], table_file: Path | None) -> None:
    """The points into ``data``: ``axes`` (each dimension's values) and ``table`` (sweep.csv's columns -> one
    value per point, in the CSV's row order), or above `JSON_MAX_POINTS` the CSV's path and a note.
    O(points (m + n))."""
    data["axes"] = {d: a.tolist() for d, a in zip(result.dims, result.axes, strict=True)}
    count = result.mu.shape[0]
    if count <= JSON_MAX_POINTS:
        columns = dict(zip(csv_header(result), sweep_table(result).T.tolist(), strict=True))
        columns["horizon"] = [int(v) for v in columns["horizon"]]
        for p in result.radii:        # a radius not computed is null; radius_<p>.reason says why
            columns[f"radius_{p}"] = [v if np.isfinite(v) else None for v in columns[f"radius_{p}"]]
        data["table"] = columns
        return
    data["table"] = None
    data["table_file"] = None if table_file is None else str(table_file)
    where = (f"they are in {table_file} (the same columns, one row per point)" if table_file is not None else
             "pass --out DIR to have them in DIR/sweep.csv")
    data["note"] = f"{count} points are more than sweep --json carries ({JSON_MAX_POINTS}): {where}"


def bursty(args: argparse.Namespace) -> CommandResult:
    """``--burstiness``: each protocol's plug-in law against the exact minimum under Gilbert channels of
    the file's average rates (`burstiness_sweep`); ``--out`` writes
    burstiness.csv and a figure.

    Examples
    --------
    Independent losses (lambda = 0): the plug-in laws are the exact minimisers; the TCP-like law stays
    exact under bursts (its cost holds only the marginals), the UDP-like law does not.

    >>> from packetloss_cvx.cli.parser import build_parser
    >>> result = bursty(build_parser().parse_args(["sweep", "pendulum_bursty", "--burstiness", "0,0.5", "-q"]))
    >>> loss = {p: np.abs(result.data[p]["relative_loss"]) for p in ("tcp", "udp")}
    >>> bool(np.all(loss["tcp"] < 1e-9)), bool(loss["udp"][0] < 1e-9 < loss["udp"][1]), result.code
    (True, True, 0)
    """
    if args.netcdf or args.dask or args.stability:
        raise InputError("--burstiness", "takes none of --netcdf, --dask, --stability")
    if getattr(args, "mean_rate", None) is not None:
        return bursty_map(args)
    ignored = [flag for flag, given in (("--shared", args.shared), ("--channel", args.channel is not None),
                                        ("--workers", args.workers is not None),
                                        ("--chunk-size", args.chunk_size != DEFAULT_CHUNK)) if given]
    if ignored:     # each Gilbert channel keeps its own average rate: there is nothing to share or chunk
        raise InputError("--burstiness", f"takes none of --shared, --channel, --workers, --chunk-size; "
                                         f"found {', '.join(ignored)}")
    system = load_system(args.file)
    correlations = number_range(args.burstiness, "--burstiness")
    with _folder(args) as out:       # claimed (checked, locked) before the work, released on any exit
        return _bursty(args, system, correlations, out)


def _bursty(args: argparse.Namespace, system: System, correlations: np.ndarray, out: RunFolder | None
            ) -> CommandResult:
    try:
        result: BurstinessSweep = burstiness_sweep(system, correlations, progress=False if args.quiet else None)
    except InputError as err:
        raise err.renamed("--burstiness") if err.field in ("correlations", "correlation") else err from None
    protocols = ("tcp", "udp") if args.protocol == "both" else (args.protocol,)
    data: dict[str, Any] = {"name": system.name, "kind": "burstiness", "rate": result.rate.tolist(),
                            "correlation": result.correlation.tolist()}
    rates = np.round(result.rate, 6).tolist()
    lines = [f"{fmt.name(system.name or args.file)}: burstiness sweep at average rates {rates}"]
    for p in protocols:
        plugin, exact = result.plugin[p], result.exact[p]
        loss = plugin_loss(plugin, exact)      # a zero minimum has a zero plug-in cost too: its loss is 0
        data[p] = {"plugin": plugin.tolist(), "exact": exact.tolist(), "relative_loss": loss.tolist()}
        worst = int(np.argmax(loss))
        if loss[worst] <= SELF_CHECK_RTOL:   # equal to rounding: the plug-in law is the exact minimiser
            lines.append(f"  {p.upper()}-like: the plug-in law is the exact minimiser at every lambda")
        else:
            lines.append(f"  {p.upper()}-like: the plug-in law loses up to {100 * loss[worst]:.3g}% against the "
                         f"exact minimum (at lambda = {result.correlation[worst]:.4g})")
    if out is not None:
        header = ",".join(["lambda"] + [f"{kind}_{p}" for p in protocols for kind in ("plugin", "exact")])
        rows = np.column_stack([result.correlation] + [col for p in protocols
                                                        for col in (result.plugin[p], result.exact[p])])
        with out.write("burstiness.csv", text=True) as handle:
            handle.write("\n".join([header] + [",".join(map(csv_number, row)) for row in rows.tolist()]) + "\n")
        from ..plots import plot_cost_lines  # matplotlib (0.2-0.7 s) only where a figure is asked for
        curves = {f"{kind} {p.upper()}-like": (result.plugin if kind == "plug-in" else result.exact)[p]
                  for p in protocols for kind in ("plug-in", "exact")}
        figure = plot_cost_lines(result.correlation, curves, xlabel=r"burstiness $\lambda = 1 - p - r$",
                                 title=f"{system.name or 'system'}: burstiness at fixed average rates")
        drawn = save_figure(figure, figure_file(args, "burstiness"), folder=out, dpi=figure_dpi(args))
        data["files"] = [str(out.path / "burstiness.csv"), str(drawn)]
        lines.append(f"  wrote burstiness.csv, {drawn.name} in {out.path}")
    return CommandResult(data, "\n".join(lines))


def bursty_map(args: argparse.Namespace) -> CommandResult:
    """``--burstiness`` with ``--mean-rate``: the (mean rate × burstiness) map of channel ``--channel`` (default 1),
    the other channels as in the file (`burstiness_map`); the JSON carries
    every
    point up to `JSON_MAX_POINTS`; ``--out`` writes burstiness_map.csv and a figure per protocol
    (burstiness_map_<protocol>.png: the exact minimum on a log scale beside the plug-in loss in %).

    Examples
    --------
    >>> from packetloss_cvx.cli.parser import build_parser
    >>> argv = ["sweep", "pendulum_bursty", "--burstiness", "0,0.8", "--mean-rate", "0.9", "--protocol", "udp", "-q"]
    >>> result = bursty_map(build_parser().parse_args(argv))
    >>> loss = np.array(result.data["udp"]["relative_loss"])          # 1 rate x 2 lambda: the pendulum's 7.9 %
    >>> result.code, loss.shape, bool(abs(loss[0, 0]) < 1e-9), round(float(loss[0, 1]), 3)
    (0, (1, 2), True, 0.079)
    """
    ignored = [flag for flag, given in (("--shared", args.shared), ("--workers", args.workers is not None),
                                        ("--chunk-size", args.chunk_size != DEFAULT_CHUNK)) if given]
    if ignored:
        raise InputError("--mean-rate", f"takes none of --shared, --workers, --chunk-size; found {', '.join(ignored)}")
    system = load_system(args.file)
    correlations = number_range(args.burstiness, "--burstiness")
    rates = number_range(args.mean_rate, "--mean-rate")
    channel = 1 if args.channel is None else args.channel
    if not 1 <= channel <= system.m:
        raise InputError("--channel", f"expected {channel_range(system.m, True)}, found {channel}")
    with _folder(args) as out:       # claimed (checked, locked) before the work, released on any exit
        try:
            result = burstiness_map(system, rates, correlations, channel - 1,
                                    progress=False if args.quiet else None)
        except InputError as err:
            names = {"correlations": "--burstiness", "correlation": "--burstiness", "rates": "--mean-rate",
                     "rate": "--mean-rate", "channel": "--channel"}
            raise err.renamed(names[err.field]) if err.field in names else err from None
        return _map_output(args, system, result, out)


def _map_output(args: argparse.Namespace, system: System, result: BurstinessMap, out: RunFolder | None
                ) -> CommandResult:
    """The map's summary, points (JSON) and, with ``out``, its CSV and figures. O(R L)."""
    protocols = ("tcp", "udp") if args.protocol == "both" else (args.protocol,)
    shape = (result.rate.size, result.correlation.size)
    data: dict[str, Any] = {"name": system.name, "kind": "burstiness-map", "channel": result.channel + 1,
                            "shape": list(shape), "rate": result.rate.tolist(),
                            "correlation": result.correlation.tolist()}
    lines = [f"{fmt.name(system.name or args.file)}: burstiness map of channel {result.channel + 1}, "
             f"{shape[0]} mean rates x {shape[1]} values of lambda (the other channels as in the file)"]
    carried = shape[0] * shape[1] <= JSON_MAX_POINTS
    for p in protocols:
        exact, loss = result.exact[p], result.relative_loss(p)
        data[p] = ({"plugin": result.plugin[p].tolist(), "exact": exact.tolist(), "relative_loss": loss.tolist()}
                   if carried else {})
        a, b = np.unravel_index(int(np.argmax(loss)), shape)
        data[p]["worst_loss"] = {"relative_loss": float(loss[a, b]), "rate": float(result.rate[a]),
                                 "correlation": float(result.correlation[b])}
        data[p]["basis"] = CHAIN_BASIS[p]
        lines.append(f"  {p.upper()}-like ({CHAIN_BASIS[p]} basis): exact minimum {np.min(exact):.6g} to "
                     f"{np.max(exact):.6g}; " + (
            "the plug-in law is the exact minimiser at every point" if loss[a, b] <= SELF_CHECK_RTOL else
            f"the plug-in law loses up to {100 * loss[a, b]:.3g}% (at mean rate {result.rate[a]:.4g}, "
            f"lambda = {result.correlation[b]:.4g})"))
    if not carried:
        where = "in burstiness_map.csv" if out is not None else "pass --out DIR to have them in DIR/burstiness_map.csv"
        data["note"] = f"{shape[0] * shape[1]} points are more than sweep --json carries ({JSON_MAX_POINTS}): {where}"
    if out is not None:
        header = ",".join(["rate", "lambda"] + [f"{kind}_{p}" for p in protocols for kind in ("plugin", "exact")])
        rate, lam = np.meshgrid(result.rate, result.correlation, indexing="ij")
        rows = np.column_stack([rate.ravel(), lam.ravel()] + [
            col.ravel() for p in protocols for col in (result.plugin[p], result.exact[p])])
        with out.write("burstiness_map.csv", text=True) as handle:
            handle.write("\n".join([header] + [",".join(map(csv_number, row)) for row in rows.tolist()]) + "\n")
        files = [out.path / "burstiness_map.csv"]
        skipped = []
        if min(shape) >= 2:
            from ..plots import plot_burstiness_map  # matplotlib (0.2-0.7 s) only where a figure is asked for
            for p in protocols:
                if not np.any(result.exact[p] > 0):
                    skipped.append(figure_file(args, f"burstiness_map_{p}"))
                    continue
                figure = plot_burstiness_map(
                    result.rate, result.correlation, result.exact[p], 100 * result.relative_loss(p),
                    cost_label=rf"exact minimum $J^*_{{\mathrm{{{p}}}}}$, {CHAIN_BASIS[p]} basis (log scale)",
                    title=f"{system.name or 'system'}: channel {result.channel + 1}, {p.upper()}-like")
                files.append(save_figure(figure, figure_file(args, f"burstiness_map_{p}"), folder=out,
                                          dpi=figure_dpi(args)))
        else:
            skipped.extend(figure_file(args, f"burstiness_map_{p}") for p in protocols)
        data["files"] = [str(f) for f in files]
        lines.append(f"  wrote {', '.join(f.name for f in files)} in {out.path}")
        if skipped:
            data["figures_not_drawn"] = skipped
            lines.append(f"  not drawn: {', '.join(skipped)} (a map needs two rates and two values of lambda, and "
                         "a positive minimum on its log scale)")
    return CommandResult(data, "\n".join(lines))


def run(args: argparse.Namespace) -> CommandResult:
    """Sweep, summarise, and with ``--out`` save the arrays and the figure.

    Examples
    --------
    One step of x' = x + v u from x0 = 1: J_Delta(nu) = 1 - nu/2 - 1/(1 + nu) is 1/12 at nu = 1/2, 0 at 0 and 1.

    >>> import tempfile
    >>> from pathlib import Path
    >>> from packetloss_cvx.model.files import save_system
    >>> from packetloss_cvx.model.system import System
    >>> from packetloss_cvx.cli.parser import build_parser
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> folder = tempfile.TemporaryDirectory()
    >>> path = str(save_system(s, Path(folder.name) / "scalar.toml"))
    >>> result = run(build_parser().parse_args(["sweep", path, "--mu-grid", "3", "-q"]))
    >>> diff = result.data["cost_diff"]
    >>> result.code, result.data["shape"], diff["argmax"], bool(np.isclose(diff["max"], 1 / 12))
    (0, [3], {'nu': 0.5}, True)
    >>> folder.cleanup()
    """
    if args.out is not None and not args.out.strip():   # an unset $DIR: not the current folder
        raise InputError("--out", "expected a folder, found an empty path")
    check_dead_flags(args)      # --format, --dpi without --out
    if getattr(args, "burstiness", None) is not None:
        return bursty(args)
    if getattr(args, "mean_rate", None) is not None:
        raise InputError("--mean-rate", "needs --burstiness (a map over mean rate and burstiness)")
    system = load_system(args.file)
    if system.channel is not None:     # the API's message names a Python function; here, the option
        raise InputError("FILE", f"{args.file} has a Gilbert-Elliott (Markov) channel; --mu-grid, --mu-list, "
                                 "--x0-scales and --horizons evaluate independent Bernoulli channels: sweep its "
                                 f"burstiness with `packetloss-cvx sweep {args.file} --burstiness 0:0.9:10`")
    protocols = ("tcp", "udp") if args.protocol == "both" else (args.protocol,)
    if args.netcdf and args.out is None:     # before the sweep, not after it
        raise InputError("--netcdf", "needs --out DIR")
    try:
        if args.netcdf:
            require_xarray()
        options = _options(args, system.m)
        with _folder(args) as out:      # claimed (checked, locked) before the sweep, released on any exit
            return _design(args, system, protocols, options, out)
    except InputError as err:
        raise err.renamed(FLAGS[err.field]) if err.field in FLAGS else err from None


def _folder(args: argparse.Namespace) -> contextlib.AbstractContextManager[RunFolder | None]:
    """``--out DIR`` as a claimed `RunFolder`, or nothing."""
    if args.out is None:
        return contextlib.nullcontext()
    return RunFolder(args.out, command=getattr(args, "command_line", "packetloss-cvx sweep"),
                     force=getattr(args, "force", False), field="--out")


def _design(args: argparse.Namespace, system: System, protocols: tuple[str, ...], options: dict[str, Any],
            out: RunFolder | None) -> CommandResult:
    try:
        result = sweep(system, protocols=protocols, shared=args.shared, chunk_size=args.chunk_size,
                       dask=args.dask, workers=args.workers, stability=args.stability,
                       progress=False if args.quiet else None, **options)
        data, lines = _summary(result)
        paths = write_sweep(result, out, netcdf=args.netcdf) if out is not None else {}
        _points(result, data, paths.get("csv"))
        if out is not None:
            skipped: list[str] = []
            paths_list = [*paths.values(), *_figures(result, out, skipped, args)]
            data["files"] = [str(p) for p in paths_list]
            lines.append(f"  wrote {', '.join(p.name for p in paths_list)} in {out.path}")
            if skipped:
                data["figures_not_drawn"] = skipped
                lines.append(f"  not drawn: {', '.join(skipped)} (no positive value: the figure shows logarithms)")
    except InputError as err:
        raise err.renamed(FLAGS[err.field]) if err.field in FLAGS else err from None
    return CommandResult(data, "\n".join(lines))
