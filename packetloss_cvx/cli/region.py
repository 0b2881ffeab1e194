"""``packetloss-cvx region FILE``: can this loop be stabilised over these links, and by which law?"""

from __future__ import annotations

import argparse
import contextlib
import csv
from pathlib import Path
from typing import Any

import numpy as np

from ..budgets import check
from ..closedloop.markov_region import (
    chain_critical_rate,
    chain_least_radius,
    chain_rate_map,
    critical_rate_unproved,
)
from ..closedloop.riccati import dp_riccati
from ..errors import InputError, NumericalError
from ..model.validation import channel_range
from ..results.region import RegionMap
from ..runfolder import RunFolder
from ..safeio import save_figure
from ..studies.output import csv_number
from ..studies.region_map import LAWS, region_map
from ..tolerances import ACTUATOR_COMPARE_TOL
from .actuator_section import actuator_strategies, critical_section
from .common import (
    CommandResult,
    check_dead_flags,
    figure_dpi,
    figure_file,
    floats,
    integers,
    progress_of,
    system_of,
)
from .format import num_within, supported
from .sensing_section import coupled_grid, region_section

__all__ = ["run"]

FLAGS = {"law": "--law", "direction": "--direction", "grid": "--grid", "channels": "--channels", "dask": "--dask",
         "workers": "--workers"}


def _options(args: argparse.Namespace, m: int) -> dict[str, Any]:
    """The command's numbers checked against the file's m: the API's errors, under the option's name."""
    options: dict[str, Any] = {"laws": LAWS if args.law == "all" else (args.law,)}
    if args.direction is not None:
        d = floats(args.direction, "--direction")
        if len(d) != m or any(not np.isfinite(v) or v < 0 for v in d) or not any(v > 0 for v in d):
            raise InputError("--direction", f"expected {m} nonnegative numbers, not all zero, found "
                                            f"{args.direction[:60]!r}")
        options["direction"] = d
    for flag, value in (("--channels", args.channels), ("--dask", args.dask), ("--workers", args.workers)):
        if value is not None and args.grid is None:
            raise InputError(flag, "needs --grid K")
    if args.workers is not None and args.dask != "local":
        raise InputError("--workers", "applies to --dask local only")
    options["dask"], options["workers"] = args.dask, args.workers
    if args.grid is not None:
        if args.grid < 2:
            raise InputError("--grid", f"expected an integer >= 2, found {args.grid}")
        if m < 2:
            raise InputError("--grid", "a map needs two channels; this system has one (its critical mu is the answer)")
        text = args.channels if args.channels is not None else "1,2"
        pair = integers(text, "--channels")       # inf and nan refused here, not by int() (exit 1)
        if len(pair) != 2 or any(not 1 <= v <= m for v in pair) or pair[0] == pair[1]:
            raise InputError("--channels", f"expected two different channels, each {channel_range(m, True)}, "
                                            f"found {text[:40]!r}")
        options["grid"] = args.grid
        options["channels"] = (pair[0] - 1, pair[1] - 1)
    return options


def run(args: argparse.Namespace) -> CommandResult:
    """Each law's critical mu along the direction and, with ``--grid``, its region over two channels.

    Examples
    --------
    One state, x' = 2x + v u: some law stabilises iff mu > 1 - 1/a^2 = 0.75.

    >>> import tempfile
    >>> from packetloss_cvx.model.files import save_system
    >>> from packetloss_cvx.model.system import System
    >>> from packetloss_cvx.cli.parser import build_parser
    >>> s = System(A=[[2.0]], B=[[1.0]], horizon=2, state_weight=[1.0], input_weight=[1.0], mu=[0.9], x0=[1.0])
    >>> folder = tempfile.TemporaryDirectory()
    >>> path = str(save_system(s, Path(folder.name) / "scalar.toml"))
    >>> result = run(build_parser().parse_args(["region", path, "--law", "dp", "-q"]))
    >>> result.code, abs(result.data["dp"]["t"] - 0.75) <= 1e-6
    (0, True)
    >>> folder.cleanup()
    """
    if args.out is not None and not args.out.strip():
        raise InputError("--out", "expected a folder, found an empty path")
    check_dead_flags(args)      # --format, --dpi without --out DIR and --grid K
    system = system_of(args)
    if system.channel is not None:
        return _chain(args, system)
    options = _options(args, system.m)
    strategies = actuator_strategies(getattr(args, "actuator", None), system)
    left_out = None
    if args.law == "all":   # 'fixed' is the DP gain at the file's mu: where none exists, the others still answer
        try:
            dp_riccati(system)
        except NumericalError as err:
            options["laws"] = tuple(law for law in options["laws"] if law != "fixed")
            left_out = f"law 'fixed' left out: the DP gain at the file's mu does not exist ({err})"
    sensor_grid = getattr(args, "sensor_grid", None)
    if sensor_grid is not None:
        if system.sensor is None:
            raise InputError("--sensor-grid", "needs a file with a [sensor] section")
        if sensor_grid < 2:
            raise InputError("--sensor-grid", f"expected an integer >= 2, found {sensor_grid}")
        check("region_points", 2 * sensor_grid * sensor_grid, "--sensor-grid",
              f"a {sensor_grid} x {sensor_grid} map of 2 laws")
    try:
        with _folder(args) as out:
            result = region_map(system, progress=progress_of(args), **options)
            data, lines = result.to_dict(), _text(result)
            if left_out is not None:
                data["notes"] = [left_out]
                lines.append(f"  {left_out}")
            if system.sensor is not None:       # lossy sensor links: thresholds (TCP-like), coupled map (UDP-like)
                data["sensor"], more = region_section(system, result.critical)
                lines += more
                if sensor_grid is not None and "reason" not in data["sensor"]:
                    data["sensor"]["grid"] = grid = coupled_grid(system, sensor_grid)
                    lines += [f"stable share of the {sensor_grid}x{sensor_grid} (gamma, mu) scale map, the paper's "
                              "law on its estimate:"] + [f"  {p:<6} {100 * grid[p]['stable_share']:.1f} %"
                                                        for p in ("tcp", "udp")]
            if strategies:                      # each actuator strategy on a loss: its own critical mu
                data["actuator"], more = critical_section(system, strategies, options.get("direction"),
                                                          ACTUATOR_COMPARE_TOL)
                lines += more
            if out is not None:
                paths = _write(result, out, args)
                data = {**data, "files": [str(p) for p in paths]}
                lines.append(f"  wrote {', '.join(p.name for p in paths)} in {out.path}")
    except InputError as err:
        raise err.renamed(FLAGS[err.field]) if err.field in FLAGS else err from None
    return CommandResult(data, "\n".join(lines))


def _chain(args: argparse.Namespace, system) -> CommandResult:
    """A Gilbert–Elliott file (simulation.markov_region): can some mode-dependent law (the last state known, as
    a TCP-like acknowledgement reveals it) stabilise the loop behind the file's chain, and, with ``--grid K``,
    where over the channels' mean rates at the file's burstiness (one channel: a row of K rates)."""
    strategies = actuator_strategies(getattr(args, "actuator", None), system)
    if args.law not in ("dp", "all"):
        raise InputError("--law", "behind a Gilbert-Elliott chain only 'dp' (some mode-dependent linear law) is "
                                  "mapped; the paper's laws are Bernoulli designs")
    for flag, value in (("--dask", args.dask), ("--workers", args.workers)):
        if value is not None:
            raise InputError(flag, "does not apply to a Gilbert-Elliott file (its map is over the mean rates: "
                                   "--grid K)")
    chain = system.channel
    direction = None
    if args.direction is not None:
        direction = floats(args.direction, "--direction")
        if (len(direction) != system.m or any(not np.isfinite(v) or v < 0 for v in direction)
                or not any(v > 0 for v in direction)):
            raise InputError("--direction", f"expected {system.m} nonnegative numbers, not all zero, found "
                                            f"{args.direction[:60]!r}")
    # lambda printed to the digits its own accuracy estimate supports (a defective root is known to about 1e-5)
    found, lam, error = chain_least_radius(system.A, system.B, chain)
    entry: dict[str, Any] = {"verdict": found.verdict, "lambda": supported(lam, error),
                             "lambda_error": None if np.isnan(error) else error,
                             "mean_rate": chain.mean_rate.tolist(),
                             "burstiness": chain.correlation.tolist(), "information": "last state known (next)",
                             "radius": None if found.verdict != "stable" else float(found.radius)}
    lines = [f"behind the file's Gilbert-Elliott chain (mean rates {np.round(chain.mean_rate, 6).tolist()}, "
             f"burstiness {np.round(chain.correlation, 6).tolist()}), a mode-dependent law knowing the last state:",
             f"  {found.verdict} (min over such laws of the mean-square radius: {num_within(lam, error)})"]
    grid = None
    if args.grid is not None:
        if args.grid < 2:
            raise InputError("--grid", f"expected an integer >= 2, found {args.grid}")
        m = system.m
        points = args.grid ** 2 if m > 1 else args.grid
        check("region_points", points, "--grid", f"a rate grid of {points} points behind the chain")
        text = args.channels if args.channels is not None else ("1,2" if m > 1 else "1")
        pair = integers(text, "--channels")
        if (len(pair) != min(m, 2) or any(not 1 <= v <= m for v in pair)
                or (len(pair) == 2 and pair[0] == pair[1])):
            raise InputError("--channels", f"expected {min(m, 2)} different channels, each "
                                           f"{channel_range(m, True)}, found {text[:40]!r}")
        channels = tuple(v - 1 for v in pair) + ((0,) if m == 1 else ())
        lo = float(np.max(chain.h_bad[list(set(channels))]))
        hi = float(np.min(chain.h_good[list(set(channels))]))
        axis = np.linspace(lo, hi, args.grid)
        stable, lams, errors = chain_rate_map(system.A, system.B, chain, axis, channels[:2], with_error=True)
        grid = {"axis": axis, "channels": channels, "stable": stable, "lambda": lams, "lambda_error": errors}
        # each point's lambda to the digits its own accuracy estimate supports, the estimate beside it
        entry["grid"] = {"axis": axis.tolist(), "channels": [c + 1 for c in channels[:m]],
                         "stable": [[None if np.isnan(v) else bool(v) for v in row] for row in stable],
                         "lambda": [[supported(v, e) for v, e in zip(row, erow, strict=True)]
                                    for row, erow in zip(lams, errors, strict=True)],
                         "lambda_error": [[None if np.isnan(e) else float(e) for e in row] for row in errors]}
        lines.append(f"stable share of the rate grid ({stable.size} points, burstiness kept): "
                     f"{100 * float(np.mean(stable == 1.0)):.1f} % ({int(np.isnan(stable).sum())} undecided)")
    entry.update(_critical_rate(system, direction, lines))      # after the grid's budget: refused before any work
    data: dict[str, Any] = {"dp": entry}
    if strategies:      # each strategy's critical mean rate (the law knows the current state: design_modes)
        data["actuator"], more = critical_section(system, strategies, direction, ACTUATOR_COMPARE_TOL)
        lines += more
    if args.out is not None:
        with _folder(args) as out:
            arrays: dict[str, Any] = {"lambda": np.array(lam), "lambda_error": np.array(error),
                                      "mean_rate": chain.mean_rate, "burstiness": chain.correlation}
            if grid is not None:
                arrays.update(axis=grid["axis"], channels=np.array(grid["channels"]) + 1, stable=grid["stable"],
                              radius=grid["lambda"], radius_error=grid["lambda_error"])
            with out.write("region.npz") as handle:
                np.savez(handle, **arrays)
            with out.write("region.csv", text=True) as handle:
                writer = csv.writer(handle)
                if grid is None:
                    writer.writerow(["verdict", "lambda"])
                    writer.writerow([found.verdict, csv_number(supported(lam, error))])
                else:
                    writer.writerow(["rate_i", "rate_j", "stable", "lambda"])      # rate_j empty for one channel
                    rows = grid["axis"] if system.m > 1 else [float("nan")]
                    for row, y in enumerate(rows):
                        for col, x in enumerate(grid["axis"]):
                            writer.writerow([csv_number(x), csv_number(y), csv_number(grid["stable"][row, col]),
                                             csv_number(supported(grid["lambda"][row, col],
                                                                  grid["lambda_error"][row, col]))])
            paths = [out.path / "region.npz", out.path / "region.csv"]
            if grid is not None and system.m > 1:
                from ..plots import plot_region  # matplotlib only where a figure is asked for
                i, j = grid["channels"][:2]
                figure = plot_region(grid["axis"], grid["lambda"], {"dp": grid["stable"]},
                                     xlabel=rf"mean rate of channel {i + 1}", ylabel=rf"mean rate of channel {j + 1}",
                                     title="stability region behind the chain (burstiness kept)")
                paths.append(save_figure(figure, figure_file(args, "region"), folder=out, dpi=figure_dpi(args)))
            data["files"] = [str(p) for p in paths]
            lines.append(f"  wrote {', '.join(p.name for p in paths)} in {out.path}")
    return CommandResult(data, "\n".join(lines))


def _critical_rate(system, direction: list[float] | None, lines: list[str]) -> dict[str, Any]:
    """The critical mean rates along ``direction`` at the file's burstiness (markov_region.chain_critical_rate),
    where monotonicity is proved; else ``critical_mu`` null with the reason."""
    reason = critical_rate_unproved(system.channel)
    if reason is not None:
        lines.append(f"  no critical mean rate: {reason}")
        return {"critical_mu": None, "t": None, "critical_mu_reason": reason}
    point = chain_critical_rate(system, direction)
    where = "never, even at the ray's end" if not np.isfinite(point.t) else (
        f"t = {point.t:.6g} (bracket [{point.lower:.6g}, {point.t:.6g}]), mean rates {np.round(point.mu, 6).tolist()}")
    lines.append(f"critical mean rates along direction {point.direction.tolist()} (burstiness kept): {where}")
    if point.note:
        lines.append(f"  ({point.note})")
    data = point.to_dict()
    return {"critical_mu": data["critical_mu"], "t": data["t"], "lower": data["lower"],
            "direction": data["direction"], "note": data["note"]}


def _folder(args: argparse.Namespace) -> contextlib.AbstractContextManager[RunFolder | None]:
    if args.out is None:
        return contextlib.nullcontext()
    return RunFolder(args.out, command=getattr(args, "command_line", "packetloss-cvx region"),
                     force=getattr(args, "force", False), field="--out")


def _text(result: RegionMap) -> list[str]:
    lines = [f"critical mu along direction {result.direction.tolist()} (some law of the kind stabilises for mu "
             "= t * direction, t above):"]
    for point in result.critical:
        where = "never, even at the ray's end" if not np.isfinite(point.t) else (
            f"t = {point.t:.6g} (bracket [{point.lower:.6g}, {point.t:.6g}]), mu = {np.round(point.mu, 6).tolist()}")
        lines.append(f"  {point.law:<6} {where}")
        if point.note:
            lines.append(f"         ({point.note})")
    if result.stable is not None:
        i, j = result.channels
        lines.append(f"stable share of the {result.axis.size}x{result.axis.size} grid of (mu{i + 1}, mu{j + 1}):")
        lines.extend(f"  {law:<6} {100 * result.area(law):.1f} %" for law in result.laws)
    return lines


def _write(result: RegionMap, out: RunFolder, args: argparse.Namespace) -> list[Path]:
    """region.npz, region.csv and (with a grid) region.png (``--format``, ``--dpi``) in the run folder ``out``."""
    arrays: dict[str, Any] = {"laws": np.array(result.laws), "direction": result.direction,
                              "t": np.array([p.t for p in result.critical]),
                              "lower": np.array([p.lower for p in result.critical])}
    if result.stable is not None:
        arrays.update(axis=result.axis, channels=np.array(result.channels) + 1, base=result.base,
                      stable=result.stable, radius=result.radius)
    with out.write("region.npz") as handle:
        np.savez(handle, **arrays)
    with out.write("region.csv", text=True) as handle:
        writer = csv.writer(handle)
        if result.stable is None:
            writer.writerow(["law", "t", "lower", *(f"mu{k + 1}" for k in range(result.direction.size))])
            for p in result.critical:
                writer.writerow([p.law, csv_number(p.t), csv_number(p.lower),
                                 *(csv_number(v) for v in p.t * p.direction)])
        else:
            i, j = result.channels
            writer.writerow(["law", f"mu{i + 1}", f"mu{j + 1}", "stable", "radius"])
            for k, law in enumerate(result.laws):
                for row, mu_j in enumerate(result.axis):
                    for col, mu_i in enumerate(result.axis):
                        cell = (result.stable[k, row, col], result.radius[k, row, col])
                        writer.writerow([law, csv_number(mu_i), csv_number(mu_j), *(csv_number(v) for v in cell)])
    paths = [out.path / "region.npz", out.path / "region.csv"]
    if result.stable is not None:
        from ..plots import plot_region  # matplotlib only where a figure is asked for
        i, j = result.channels
        radius = dict(zip(result.laws, result.radius, strict=True))
        if "dp" not in radius:          # the colours are the least radius, which only the dp law computes
            radius = {"dp": np.full(result.radius.shape[1:], np.nan), **radius}
        figure = plot_region(result.axis, radius, dict(zip(result.laws, result.stable, strict=True)),
                             xlabel=rf"$\mu_{i + 1}$", ylabel=rf"$\mu_{j + 1}$",
                             title=f"{result.name or 'system'}: where each law stabilises the loop in mean square"
                             if hasattr(result, "name") else "where each law stabilises the loop in mean square")
        paths.append(save_figure(figure, figure_file(args, "region"), folder=out, dpi=figure_dpi(args)))
    return paths
