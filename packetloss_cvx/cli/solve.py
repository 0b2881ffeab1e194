"""``packetloss-cvx solve FILE``: optimal plans, costs and gains, cross-checked by a QP, and whether
each receding-horizon law is mean-square stable when run in a loop over the file's channel."""

from __future__ import annotations

import argparse
from types import SimpleNamespace
from typing import Any

import numpy as np

from ..closedloop.law_stability import STABILITY_MAX_N, loop_stability
from ..display import SOLUTION_BASIS, all_delivered_flag
from ..errors import InfeasibleError, NumericalError, ResourceError, SolverError
from ..lq.costs import closed_form
from ..lq.markov_cost import exact_cost
from ..model.constraints import Constraints
from ..model.system import System
from ..progress import progress_bar
from ..results import Solution, eigenvalue_pairs
from . import format as fmt
from .actuator_section import actuator_entry, actuator_strategies
from .common import CommandResult, constraints_of, progress_of, system_of
from .markov_section import PRIOR_MEAN_BASIS, markov_section
from .sensing_section import estimation_section, protocol_entry

__all__ = ["STABILITY_MAX_N", "constrained_entry", "run", "stability", "text_details"]


def run(args: argparse.Namespace) -> CommandResult:
    """Both protocols' closed forms, each compared with its QP twin (a disagreement raises). Exit code 1 where a
    constrained program asked for was not solved (status "failed": a solver error or an untrusted answer); the
    result is still printed in full.

    Examples
    --------
    One step of x' = x + v u from x0 = 1 (Q = R = 1, mu = 0.5): `J*_tcp` = 1/(1 + mu) = 2/3 with u = -2/3 x,
    `J*_udp` = 1 - mu/2 = 0.75 with u = -x/2.

    >>> import tempfile
    >>> from pathlib import Path
    >>> from packetloss_cvx.model.files import save_system
    >>> from packetloss_cvx.cli.parser import build_parser
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> folder = tempfile.TemporaryDirectory()
    >>> path = str(save_system(s, Path(folder.name) / "scalar.toml"))
    >>> result = run(build_parser().parse_args(["solve", path, "--no-qp"]))
    >>> result.code, bool(np.isclose(result.data["tcp"]["cost"], 2 / 3)), result.data["udp"]["cost"]
    (0, True, 0.75)
    >>> bool(np.isclose(result.data["tcp"]["gain"][0][0], 2 / 3)), "qp" in result.data["tcp"]
    (True, False)
    >>> folder.cleanup()
    """
    system = system_of(args)
    constraints = constraints_of(args, system)     # the file's [constraints] table and its overrides, or None
    strategies = actuator_strategies(getattr(args, "actuator", None), system)     # refused before any work
    protocols = ("tcp", "udp") if args.protocol == "both" else (args.protocol,)
    out: dict[str, Any] = {
        "name": system.name, "n": system.n, "m": system.m, "horizon": system.horizon,
        "mu": system.mu_schedule[0].tolist() if system.is_stationary else system.mu_schedule.tolist(),
    }
    mu = fmt.numbers(system.mu_schedule[0]) if system.is_stationary else "non-stationary (per step)"
    lines = [f"{fmt.name(system.name or args.file)}: n={system.n}, m={system.m}, N={system.horizon}, mu = {mu}"]
    # behind a Gilbert-Elliott chain the paper's laws are the plug-in laws (Bernoulli losses at the chain's
    # predicted mu_t), labelled so; the exact costs under the chain are the "markov" section's
    plugin = system if system.channel is None else system.with_mu(system.mu_schedule)
    for protocol in progress_bar(protocols, desc="solve", progress=progress_of(args)):   # minutes at large n
        sol = closed_form(plugin, protocol, method=args.method)
        entry: dict[str, Any] = {
            "protocol": protocol, "cost": sol.cost, "inputs": sol.inputs.tolist(), "gain": sol.gain.tolist(),
            "closed_loop_eigenvalues": eigenvalue_pairs(sol.closed_loop_eigenvalues),
            "method": sol.method, "basis": SOLUTION_BASIS,
        }
        acts, entry["gain_note"] = gain_rows(plugin.mu_schedule[0])
        entry["gain_acts"] = acts.tolist()
        entry["cost_note"] = OPEN_LOOP_NOTE if not np.any(plugin.mu_schedule) else None
        label = f"J* = {sol.cost:.10g} ({sol.method}) [basis: {SOLUTION_BASIS}]"
        if plugin is not system:
            entry["plug_in"], entry["basis"] = True, PRIOR_MEAN_BASIS
            label = (f"J* = {sol.cost:.10g} ({sol.method}) [basis: {PRIOR_MEAN_BASIS}]: the paper's formula on the "
                     "chain's mu_t, not the expected cost under the chain (below" + (
                         ", beside the attainable cost with acknowledgements)" if protocol == "tcp" else ")"))
        if entry["cost_note"]:
            label += f": {OPEN_LOOP_NOTE}"
        rows: list[tuple[str, object]] = [("cost", label)]
        if not args.no_qp:
            from ..qp.expected_cost import solve_qp  # cvxpy (1.5 s to import) only where a QP is asked for

            try:
                qp = solve_qp(plugin, protocol, args.formulation, with_gain=False, reference=sol)
            except (NumericalError, ResourceError) as err:   # a disagreement (CrossCheckError) is not caught
                entry["qp"] = {"status": "skipped", "reason": str(err)}
                rows.append(("cross-check", f"QP cross-check skipped: {err}"))
            else:
                check = qp.cross_check
                entry["qp"] = {
                    "status": qp.status, "cost": qp.cost, "solve_time": qp.solve_time,
                    "formulation": qp.method.removeprefix("qp-"),
                    "max_input_diff": check.max_input_diff, "cost_rel_diff": check.cost_rel_diff,
                    "basis": entry["basis"],        # the same quantity as J* above, on its basis
                }
                timing = f", {qp.solve_time:.3g} s" if args.verbose else ""
                rows.append(("cross-check", f"QP {qp.status}, J = {qp.cost:.10g} (paper), max|Vbar dU| = "
                                            f"{check.max_input_diff:.1e}, rel dJ = {check.cost_rel_diff:.1e}{timing}"))
        if constraints is not None:
            entry["constrained"], text = constrained_entry(plugin, protocol, constraints, args,
                                                           chain=system if plugin is not system else None)
            rows.append(("constrained", text))
            entry["law_note"] = unconstrained_note(args.file)
        rows += text_details(sol, system.n, args.verbose, acts=acts, A=plugin.A, B=plugin.B,
                             unconstrained=constraints is not None)
        flag = all_delivered_flag(sol) if acts.all() else None if not acts.any() else all_delivered_flag(
            SimpleNamespace(closed_loop_eigenvalues=acting_eigenvalues(plugin.A, plugin.B, sol.gain, acts)))
        if flag is not None and not acts.all():
            flag += f"; {idle_inputs(acts)} never delivered"
        if flag is not None:
            rows.append(("all delivered", flag))
        if system.sensor is not None:     # lossy sensor links: the law on the protocol's estimate
            entry["estimated_state"], text = protocol_entry(system, protocol, sol.gain)
            rows.append(("estimated state", text))
        wanted = getattr(args, "stability", None)
        if wanted is False or (wanted is None and system.n > STABILITY_MAX_N):
            why = ("skipped (--no-stability)" if wanted is False else
                   f"skipped for n = {system.n} > {STABILITY_MAX_N} (it can take minutes): add --stability to "
                   "compute it")
            entry.update({"mean_square_spectral_radius": None, "stable": False,
                          "stability_note": f"not computed: {why}"})
            rows.append(("closed loop", f"stability not computed: {why}"))
        else:
            rows.append(("closed loop", stability(system, sol.gain, entry)))
        if constraints is not None:     # the gain and its verdict are the closed form's, blind to the constraints
            label, said = rows[-1]
            rows[-1] = (label, f"{said}; the unconstrained law's loop (the constrained loop: simulate {args.file} "
                               "with the same constraints)")
        if strategies:      # the law's loop when the actuator zeroes, holds or plays the buffered plan on a loss
            entry["actuator"], more = actuator_entry(system, sol.gain, strategies, system.horizon)
            rows.append(("on a loss", more))
        out[protocol] = entry
        lines += ["", f"{protocol.upper()}-like"] + fmt.fields(rows)
    if system.sensor is not None:
        out["estimation"], more = estimation_section(system)
        lines += ["", "Lossy sensor links (estimated state)"] + [f"  {line}" for line in more]
    if system.channel is not None:   # Gilbert-Elliott: the exact minimiser under the chain beside the plug-in laws
        out["markov"], more = markov_section(system, protocols, qp=not args.no_qp)
        model = system.channel.to_dict()["model"]
        heading = "Gilbert-Elliott channel" if model == "gilbert-elliott" else "Markov channel"
        lines += ["", heading] + [line.strip() for line in more]
    # a constrained program asked for that the solver did not solve is a failed computation (exit 1), printed in full
    failed = [p for p in protocols if out[p].get("constrained", {}).get("status") == "failed"]
    if failed:
        which = ", ".join(f"{p.upper()}-like" for p in failed)
        lines += ["", f"not solved: the constrained program of {which} (exit 1)"]
    return CommandResult(out, "\n".join(lines), 1 if failed else 0)


def constrained_entry(system: System, protocol: str, constraints: Constraints,
                      args: argparse.Namespace, chain: System | None = None) -> tuple[dict[str, Any], str]:
    """The ``"constrained"`` JSON entry of one protocol and its text: the file's ``[constraints]`` solved by
    `solve_constrained` ({"status", "cost", "basis", "plan_expected_cost", "inputs", "binding", ...}); a proven
    infeasibility (a verified certificate) is reported as status "infeasible" with the solver's status and reason,
    a solver's "infeasible" whose certificate is undecided as status "undecided" with the certificate's reason (the
    closed forms above stand), never replaced by another plan. ``--no-qp`` skips it (status "skipped"). The cost
    says its basis: TCP-like "paper" (J_tcp(U), without the loss variance), beside the plan's exact expected cost
    (basis "realised", ``plan_expected_cost_basis``); UDP-like "realised". Behind a chain (``chain``, the file's
    system; ``system`` its Bernoulli plug-in twin) the program is the plug-in one, ``"plug_in": true``, basis
    "paper, prior-mean rates", but for its chance rows, posed with the deliveries' covariance under the chain
    (``"chance_rows": "exact under the chain"``), and ``plan_expected_cost`` is the plan's exact expected cost under
    the chain (`exact_cost`), what the plan realises.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> entry, text = constrained_entry(s, "tcp", Constraints(u_min=[-0.5]), argparse.Namespace(no_qp=False))
    >>> entry["status"], entry["binding"], round(entry["inputs"][0][0], 6)
    ('optimal', ['u_min[0] at t=0'], -0.5)
    """
    if getattr(args, "no_qp", False):
        return {"status": "skipped", "reason": "--no-qp"}, "skipped (--no-qp)"
    from ..qp.constrained import solve_constrained  # cvxpy only where a QP is asked for

    try:
        sol = solve_constrained(system if chain is None else chain, protocol, constraints,
                                getattr(args, "formulation", "auto"))
    except InfeasibleError as err:
        certificate = err.certificate or {}
        return ({"status": "infeasible", "solver_status": err.status, "cost": None, "inputs": None, "binding": [],
                 "certificate": {"verdict": certificate.get("verdict"), "reason": certificate.get("reason"),
                                 "margin": certificate.get("margin")},
                 "reason": str(err)}, f"infeasible: {err}")
    except SolverError as err:
        if err.certificate is not None:      # "infeasible" said by the solver, its certificate not verified
            certificate = err.certificate
            return ({"status": "undecided", "solver_status": err.status, "cost": None, "inputs": None, "binding": [],
                     "certificate": {"verdict": certificate.get("verdict"), "reason": certificate.get("reason"),
                                     "margin": certificate.get("margin")},
                     "reason": str(err)}, f"undecided: {err}")
        return ({"status": "failed", "cost": None, "inputs": None, "binding": [], "reason": str(err)},
                f"not solved: {err}")
    except NumericalError as err:
        return ({"status": "failed", "cost": None, "inputs": None, "binding": [], "reason": str(err)},
                f"not solved: {err}")
    bound = ", ".join(sol.binding[:6]) + (f", ... ({len(sol.binding)} in all)" if len(sol.binding) > 6 else "")
    entry = sol.to_dict()
    entry["plan_expected_cost_basis"] = "realised"      # "basis" is the cost's; the plan's expected cost is realised
    realised = sol.plan_expected_cost
    if chain is not None:         # the plug-in program: its plan's cost under the chain is what it realises
        try:
            realised = exact_cost(chain, sol.inputs, "udp")
        except NumericalError:
            realised = None
        entry.update({"plug_in": True, "basis": PRIOR_MEAN_BASIS, "plan_expected_cost": realised})
        where = " under the chain"
        label = (f"J = {sol.cost:.10g} [basis: {PRIOR_MEAN_BASIS}: the plug-in program, its cost on Bernoulli losses "
                 f"at the chain's mu_t, its chance rows {sol.chance_rows} (the deliveries' covariance)] ({sol.status})")
    else:
        where = ""
        label = (f"J = {sol.cost:.10g} [basis: {sol.basis}" + (": leaves out the loss variance" if sol.basis ==
                                                                   "paper" else ": the plan's expected cost")
                 + f"] ({sol.status})")
    if chain is not None or sol.basis == "paper":
        shown = "not resolved in double precision" if realised is None else f"{realised:.10g}"
        label += f"; its plan's expected cost{where} {shown} [basis: realised]"
    if sol.violations:      # soft rows the plan breaks (positive slack): said before what merely binds
        broken = {name for name, _ in sol.violations}
        shown = ", ".join(f"{name} by {by:.3g}" for name, by in sol.violations[:6]) + (
            f", ... ({len(sol.violations)} in all)" if len(sol.violations) > 6 else "")
        held = [name for name in sol.binding if name not in broken]
        bound = ", ".join(held[:6]) + (f", ... ({len(held)} in all)" if len(held) > 6 else "")
        return entry, f"{label}; soft rows violated: {shown}; binding: {bound or 'none'}"
    return entry, f"{label}; binding: {bound or 'none'}"


def unconstrained_note(file: str) -> str:
    """The JSON's ``law_note`` where constraints are given: the gain, its eigenvalues and its loop's verdict are the
    unconstrained law's (the closed form's), which may break every bound; the constrained loop is `simulate`'s.

    Examples
    --------
    >>> unconstrained_note("plant.toml")[:64]
    'gain, closed_loop_eigenvalues and the stability verdict are the '
    """
    return ("gain, closed_loop_eigenvalues and the stability verdict are the unconstrained law's (the closed form's "
            "u = -K x, blind to the constraints, which only the \"constrained\" plan keeps); the constrained loop: "
            f"simulate {file} with the same constraints")


#: the cost's note where no channel ever delivers (every mu_t = 0): the inputs drop out of both protocols' costs
OPEN_LOOP_NOTE = "the open-loop cost (no input is ever delivered, so every plan realises it)"


def gain_rows(mu: np.ndarray) -> tuple[np.ndarray, str | None]:
    """Which rows of the receding-horizon gain act (their channel delivers at the first step, mu_i > 0) and a note
    on the rest, or None when every row acts. A row whose channel never delivers (mu_i = 0) is the limit of the
    optimal row as mu_i -> 0 (its Hessian factor G stays invertible): any value is optimal, none reaches the plant.

    Examples
    --------
    >>> gain_rows(np.array([0.5, 0.9]))
    (array([ True,  True]), None)
    >>> gain_rows(np.array([0.0, 0.5]))[1]
    'u1 (mu = 0) is never delivered: its row of K never acts (shown: its limit as mu -> 0)'
    >>> gain_rows(np.array([0.0]))[1][:48]
    'no channel delivers (mu = 0): no row of K acts, '
    """
    acts = np.asarray(mu) > 0.0        # a boolean array (acts itself) gives the same
    if acts.all():
        return acts, None
    if not acts.any():
        return acts, ("no channel delivers (mu = 0): no row of K acts, the loop is x+ = A x (the gain in --json: its "
                      "limit as mu -> 0)")
    verb = "is" if (~acts).sum() == 1 else "are"
    return acts, (f"{idle_inputs(acts)} (mu = 0) {verb} never delivered: its row of K never acts (shown: its limit "
                  "as mu -> 0)")


def idle_inputs(acts: np.ndarray) -> str:
    """The inputs whose rows never act, as the text names them: ``"u1, u3"``."""
    return ", ".join(f"u{i + 1}" for i in np.flatnonzero(~acts))


def acting_eigenvalues(A: np.ndarray, B: np.ndarray, gain: np.ndarray, acts: np.ndarray) -> np.ndarray:
    """Eigenvalues of ``A - B K`` with the rows of K that never act (``acts`` False) dropped: the loop with every
    packet delivered that can be; ``A``'s own where no row acts.

    Examples
    --------
    >>> acting_eigenvalues(np.diag([2.0, 0.5]), np.eye(2), np.diag([2.0, 0.25]), np.array([False, True]))
    array([2.  , 0.25])
    """
    return np.linalg.eigvals(A - B[:, acts] @ gain[acts])


def text_details(sol: Solution, n: int, verbose: int, acts: np.ndarray | None = None, A: np.ndarray | None = None,
                 B: np.ndarray | None = None, unconstrained: bool = False) -> list[tuple[str, object]]:
    """The gain, the closed-loop eigenvalues (the JSON's order) and, with ``-v``, the plan U*. Where ``acts``
    (`gain_rows`) marks rows of K that never act, the system's ``A`` and ``B`` give the eigenvalues without them
    (`acting_eigenvalues`), and the gain line says which rows never act (none: no matrix). ``unconstrained`` (the
    command was given constraints) labels the gain as the unconstrained law's.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> sol = closed_form(s, "udp")                 # u = -x/2: A - B K = 1/2
    >>> [label for label, _ in text_details(sol, 1, 0)], [label for label, _ in text_details(sol, 1, 1)][-1]
    (['K (u = -K x)', 'eig(A - B K)'], 'U* (row t)')
    >>> text_details(sol, 1, 0)[1][1]
    '0.5'
    """
    m = sol.inputs.shape[1]
    gain: object = fmt.matrix(sol.gain, fmt.labels("u", m), fmt.labels("x", n))
    eigs = fmt.eigenvalues(sol.closed_loop_eigenvalues)
    extra: list[tuple[str, object]] = []
    if acts is not None and not acts.all():
        if A is None or B is None:
            raise TypeError("text_details: rows of K that never act need the system's A and B")
        eigs = fmt.eigenvalues(acting_eigenvalues(A, B, sol.gain, acts))
        note = gain_rows(acts)[1]
        if acts.any():
            extra = [("never acts", note)]
            eigs += f" ({idle_inputs(acts)} dropped: never delivered)"
        else:
            gain = note
            eigs += " (no row acts: A's own)"
    label = "K (u = -K x, the unconstrained law)" if unconstrained else "K (u = -K x)"
    rows: list[tuple[str, object]] = [(label, gain), *extra, ("eig(A - B K)", eigs)]
    if verbose:
        plan = fmt.matrix(sol.inputs, [f"t={t}" for t in range(len(sol.inputs))], fmt.labels("u", m))
        rows.append(("U* (row t)", plan))
    return rows


def stability(system: System, gain: np.ndarray, entry: dict[str, Any]) -> str:
    """Mean-square stability of the receding-horizon law u = -K x run for ever over the file's channel
    ([`loop_stability`][packetloss_cvx.closedloop.law_stability.loop_stability]); adds its keys to ``entry``, returns
    the sentence.

    Examples
    --------
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> entry = {}
    >>> "mean-square stable" in stability(s, np.array([[2 / 3]]), entry), entry["stable"]
    (True, True)
    """
    verdict = loop_stability(system, gain)
    entry.update(verdict.to_dict())
    return verdict.verdict
