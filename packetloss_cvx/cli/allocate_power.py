"""``allocate FILE`` with transmit power (``--power``, the file's ``[power]`` table) or ``--protocol best``
(the acknowledgement link priced). `.allocate` hands these over; this module reads the
options, calls [`packetloss_cvx.allocation.power`][packetloss_cvx.allocation.power] / `ack` (the model from
`delivery`) and shapes the
result (exit 0 optimal, 3 infeasible, 4 gap not certified)."""

from __future__ import annotations

import argparse
from typing import Any

from ..allocation import parse_constraint
from ..allocation.ack import best_protocol
from ..allocation.delivery import PowerModel, load_power, power_model
from ..allocation.power import least_cost_within_power, least_power
from ..errors import InfeasibleError, InputError
from ..model.files import read_csv_rows
from ..model.system import System
from . import format as fmt
from .common import WARNING_ADVICE, CommandResult, attained_rows, floats, number, progress_of, search_options

__all__ = ["POWER_OPTIONS", "model_of", "run", "wants_power"]

#: the options that ask for power (any of them switches allocate to power)
POWER_OPTIONS = ("power", "power_scale", "power_table", "budget", "power_max", "ack_power")

#: the API's argument names -> the flags that set them
FLAGS = {"alpha": "--alpha", "beta": "--beta", "budget": "--budget", "max_power": "--power-max", "gap": "--gap",
         "max_boxes": "--max-boxes", "time_limit": "--time-limit", "ack_price": "--ack-price",
         "power.scale": "--power-scale", "power.table": "--power-table", "power.model": "--power"}


def wants_power(args: argparse.Namespace, system: System) -> bool:
    """Power when a power option is given, or when the file has a ``[power]`` table and no ``--beta``."""
    if any(getattr(args, name, None) is not None for name in POWER_OPTIONS):
        return True
    return args.beta is None and load_power(args.file, system.m) is not None


def model_of(args: argparse.Namespace, system: System) -> PowerModel:
    """The power model: the command line's options over the file's ``[power]`` table."""
    m = system.m
    given = args.power is not None or args.power_scale is not None or args.power_table is not None
    from_file = load_power(args.file, m)
    if not given:
        if from_file is None:
            raise InputError("--power", "give a model (exponential, rayleigh, table) with --power-scale or "
                                        "--power-table, or a [power] table in the system file")
        return from_file
    kind = args.power or (from_file.kind if from_file is not None else None)
    if kind is None:
        raise InputError("--power", "required with --power-scale or --power-table (or a [power] table in the file)")
    scale = floats(args.power_scale, "--power-scale") if args.power_scale is not None else (
        from_file.scale if from_file is not None and from_file.kind == kind and kind != "table" else None)
    csv = read_csv_rows(args.power_table, "--power-table") if args.power_table is not None else None
    if csv is None and kind == "table" and from_file is not None and from_file.kind == "table":
        return from_file
    try:
        return power_model(kind, m, scale=scale, table=None if csv is None else csv.rows,
                           lines=None if csv is None else csv.lines)     # errors cite the file's lines
    except InputError as err:
        raise (err.renamed(FLAGS[err.field]) if err.field in FLAGS else err) from None


def _options(args: argparse.Namespace, system: System, power: bool) -> dict[str, Any]:
    options: dict[str, Any] = {}
    options.update(search_options(args))
    if power and args.power_max is not None:
        options["max_power"] = floats(args.power_max, "--power-max")
    name = "P" if power else "mu"
    options["constraints"] = [parse_constraint(text, system.m, "--constraint", name=name)
                              for text in args.constraint or []]
    return options


def run(args: argparse.Namespace, system: System) -> CommandResult:
    """Power (least total power with ``--alpha``, least J* with ``--budget``) or ``--protocol best``.

    Examples
    --------
    One step of x' = x + v u from x0 = 1: J*_tcp = 1/(1 + mu) <= 0.8 needs mu = 1/4, P = log(4/3) when
    mu = 1 - exp(-P).

    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> from packetloss_cvx.model.files import save_system
    >>> from packetloss_cvx.cli.parser import build_parser
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> folder = tempfile.TemporaryDirectory()
    >>> path = str(save_system(s, Path(folder.name) / "scalar.toml"))
    >>> args = build_parser().parse_args(["allocate", path, "--protocol", "tcp", "--alpha", "0.8", "--power",
    ...                                   "exponential", "--power-scale", "1"])
    >>> result = run(args, s)
    >>> result.code, result.data["status"], bool(abs(result.data["total_power"] - np.log(4 / 3)) < 1e-4)
    (0, 'optimal', True)
    >>> folder.cleanup()
    """
    power = wants_power(args, system)
    model = model_of(args, system) if power else None
    if not power and args.beta is None:
        raise InputError("--beta", "required (or buy power: --power)")
    if power and args.beta is not None:
        raise InputError("--beta", "prices of mu do not apply when buying power (--power); drop one of them")
    if args.alpha is None and args.budget is None:
        raise InputError("--alpha", "required" + (" (or --budget)" if power else ""))
    if args.alpha is not None and args.budget is not None:
        raise InputError("--budget", "give --alpha (least power with J* <= alpha) or --budget (least J*), not both")
    options = _options(args, system, power)
    name = fmt.name(system.name or args.file)
    try:
        if args.protocol == "best":
            return _best(args, system, model, options, name)
        if args.budget is not None:
            result = least_cost_within_power(system, args.protocol, model, number(args.budget, "--budget"),
                                             **options)
        else:
            result = least_power(system, args.protocol, model, number(args.alpha, "--alpha"),
                                 progress=progress_of(args), **options)
    except InputError as err:
        raise (err.renamed(FLAGS[err.field]) if err.field in FLAGS else err) from None
    except InfeasibleError as err:
        data = {"protocol": args.protocol, "power": None, "total_power": None, "mu": None, "cost": None,
                "status": "infeasible", "gap": None, "min_cost": err.min_cost, "model": model.to_dict()}
        return CommandResult(data, f"infeasible: {err}", 3)
    data = result.to_dict()
    least = result.problem == "least-power"
    rows = [("model", f"{model.kind}, c = {fmt.numbers(model.scale)}" if model.scale is not None else
             f"table of {len(model.powers)} rows"),
            ("power", fmt.numbers(result.power)), ("total power", fmt.num(result.total_power)),
            ("mu", fmt.numbers(result.mu)),
            ("J*, paper", f"{fmt.num(result.cost, 10)} " + (f"<= alpha = {fmt.num(result.limit)}" if least else "")),
            *attained_rows(result),
            ("lower bound", f"{fmt.num(result.lower_bound)} on "
                            f"{'the total power' if least else 'the paper J*'} (proved)"),
            ("gap", f"{result.gap:.1e}"),
            ("method", result.method + (f", {result.boxes} boxes" if result.boxes else ""))]
    what = "least total power" if least else f"least paper J* within a total power of {fmt.num(result.limit)}"
    warning = [] if result.warning is None else [result.warning + WARNING_ADVICE]
    if result.status == "optimal":
        return CommandResult(data, "\n".join([f"{args.protocol.upper()}-like: {what} for {name}"] + fmt.fields(rows)
                                             + warning))
    heading = f"{args.protocol.upper()}-like: GAP NOT CERTIFIED, {what} for {name} (gap reached {result.gap:.1e})"
    return CommandResult(data, "\n".join([heading] + fmt.fields(rows + [("advice", "raise --max-boxes or "
                                                                         "--time-limit, or --gap")]) + warning), 4)


def _best(args: argparse.Namespace, system: System, model: PowerModel | None, options: dict[str, Any],
          name: str) -> CommandResult:
    if args.budget is not None:
        raise InputError("--budget", "--protocol best compares the two designs for one --alpha")
    if model is None and args.ack_power is not None:
        raise InputError("--ack-power", "prices the link in power: buy power too (--power), or use --ack-price")
    if model is not None and args.ack_price is not None:
        raise InputError("--ack-price", "with power the link costs power: use --ack-power")
    price = args.ack_power if model is not None else args.ack_price
    flag = "--ack-power" if model is not None else "--ack-price"
    ack = 0.0 if price is None else number(price, flag)
    if ack < 0:
        raise InputError(flag, f"expected a price >= 0, found {ack:g}")
    alpha = number(args.alpha, "--alpha")
    beta = None if model is not None else floats(args.beta, "--beta")
    if beta is not None and len(beta) != system.m:
        raise InputError("--beta", f"expected {system.m} comma-separated numbers, found {len(beta)}")
    try:
        choice = best_protocol(system, alpha, beta, ack, model, **options)
    except InfeasibleError as err:
        data = {"protocol": "best", "alpha": alpha, "choice": None, "status": "infeasible", "tcp": None, "udp": None,
                "min_cost": err.min_cost}
        return CommandResult(data, f"infeasible: {err}", 3)
    data = choice.to_dict()
    designs = [choice.tcp] + ([choice.udp] if choice.udp is not None else [])
    certified = all(d.status == "optimal" for d in
                    designs + ([choice.tcp_attainable] if choice.tcp_attainable is not None else []))
    data["status"] = "optimal" if certified else "gap_not_certified"
    unit = "total power" if model is not None else "beta'mu"

    def line(design, total: float, extra: str) -> str:
        if design is None:
            return "no design meets alpha (proved)"
        spent = design.power if model is not None else design.mu
        attained = ("not computed" if design.attainable_cost is None else fmt.num(design.attainable_cost))
        paper = "" if design.basis == "attainable" else f"J* {fmt.num(design.cost)} paper, "
        # the design's own gap: its mu is one point within it (where the optimum is flat, another BLAS kernel's
        # search ends at another such point: two_actuator's attainable mu moved 8e-5 under a gap of 9.4e-5)
        return (f"{fmt.num(total)} {extra}(" + ("power " if model is not None else "mu ") + fmt.numbers(spent)
                + f", {paper}{attained} attainable; gap {design.gap:.1e})")

    dp = choice.tcp_attainable
    checked = "" if choice.certified else " (within the designs' gaps: not certified)"
    if dp is None:
        rows = [("TCP, paper", line(choice.tcp, choice.tcp_total, f"= {unit} + ack {fmt.num(ack)} ")),
                ("TCP, attainable", choice.attainable_note),
                ("UDP-like", line(choice.udp, choice.udp_total, "")),
                ("choice", f"{choice.choice.upper()}-like on the paper's basis{checked}"),
                ("break-even ack", (f"UDP-like wins above {fmt.num(choice.break_even)} on the paper's basis "
                                    "(J*_tcp, which no controller attains)" if choice.udp is not None
                                    else "none: only the TCP-like protocol meets alpha"))]
    else:
        rows = [("TCP, paper", line(choice.tcp, choice.tcp_total, f"= {unit} + ack {fmt.num(ack)} ")),
                ("TCP, attainable", line(dp, choice.tcp_total_attainable, f"= {unit} + ack {fmt.num(ack)} ")),
                ("UDP-like", line(choice.udp, choice.udp_total, "")),
                ("choice", f"{choice.choice_attainable.upper()}-like on the attainable basis, "
                           f"{choice.choice.upper()}-like on the paper's{checked}"),
                ("break-even ack", (f"attainable {fmt.num(choice.break_even_attainable)}, paper "
                                    f"{fmt.num(choice.break_even)}: UDP-like wins above it; use the attainable one "
                                    "(the paper's J*_tcp is a first-moment lower bound no controller attains)"
                                    if choice.udp is not None else "none: only the TCP-like protocol meets alpha"))]
    heading = f"best protocol for {name} at alpha = {fmt.num(alpha)} ({unit})"
    warned = [f"{d.protocol.upper()}-like design: {d.warning.removeprefix('warning: ')}" for d in designs
              if d.warning is not None]
    warning = [] if not warned else ["warning: " + "; ".join(warned) + WARNING_ADVICE]
    return CommandResult(data, "\n".join([heading] + fmt.fields(rows) + warning), 0 if certified else 4)
