"""The lossy-sensor parts of ``solve``, ``simulate --closed-loop`` and ``region``: only for a
system with a ``[sensor]`` section; a full-state file's output is unchanged."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..closedloop.critical import critical_mu
from ..closedloop.riccati import dp_riccati
from ..errors import InputError, NumericalError
from ..lq.costs import closed_form
from ..model.system import System
from ..results.base import finite_or_none
from ..results.region import CriticalPoint
from ..results.sensing import EstimatedRun
from ..sensing.bounds import covariance_bounds, critical_gamma
from ..sensing.loop import estimated_loop, loop_map, loop_verdict, require_sensor
from ..sensing.markov_bounds import filter_stability, markov_covariance_bounds
from ..sensing.montecarlo import simulate_estimated

__all__ = ["coupled_grid", "estimated_law", "estimation_section", "protocol_entry", "region_section",
           "simulate_section"]


def _num(value: float | None, digits: int = 6) -> str:
    return f"{value:.{digits}g}" if value is not None and np.isfinite(value) else "n/a"


def estimation_section(system: System) -> tuple[dict[str, Any], list[str]]:
    """``solve``'s "estimation": the critical arrival rate (lower = upper where exact) along the file's gamma
    direction and the stationary bounds on tr E[P^-] (TCP-like filter), the DP law on the estimate (TCP-like:
    the optimum by separation), and text lines. O(critical_gamma + one loop)."""
    refused = _refused(system)
    if refused is not None:
        return {"critical_gamma": {"lower": None, "upper": None}, "error_covariance_trace": {"lower": None,
                "upper": None}, "reason": refused}, [f"not computed: {refused}"]
    sensor = system.sensor
    if sensor.channel is not None:
        out, lines = _chain_estimation(system)
    else:
        direction = sensor.gamma / sensor.gamma.max() if sensor.gamma.max() > 0 else np.ones(sensor.g)
        cg = critical_gamma(system.A, sensor, direction)
        bounds = covariance_bounds(system.A, system.noise_cov, sensor)
        scale = float(sensor.gamma.max())
        out = {
            "gamma": sensor.gamma.tolist(), "groups": [list(g) for g in sensor.groups],
            "critical_gamma": {"lower": finite_or_none(cg.lower), "upper": finite_or_none(cg.upper),
                               "exact": cg.exact, "direction": cg.direction.tolist(), "reason": cg.reason},
            "error_covariance_trace": {**bounds.to_dict(), "of": "the stationary E[P(k+1|k)] of the TCP-like filter"},
            "gamma_scale": scale,
        }
        where = "gamma = t d, d = gamma / max gamma; the file's t = " + _num(scale)
        lines = [f"critical rate t_c: [{_num(cg.lower)}, {_num(cg.upper)}]" + (" (exact)" if cg.exact else "")
                 + f" along {where}",
                 f"tr E[P-] (stationary, TCP-like filter): [{_num(bounds.trace_lower)}, {_num(bounds.trace_upper)}]"]
    try:
        dp = dp_riccati(system)
    except NumericalError as err:
        out["dp"] = {"cost": None, "basis": "loop", "reason": str(err)}
        lines.append(f"DP law on the estimate: no law: {err}")
    else:
        out["dp"] = estimated_law(system, dp.gain, "tcp", "dp")
        lines.append("DP law on the TCP-like estimate (optimal by separation): " + _law_text(out["dp"]))
    return out, lines


#: Why a Gilbert-Elliott sensor has no critical arrival rate in solve's "estimation".
CHAIN_CRITICAL = ("Gilbert-Elliott sensor links: the long-run rate alone does not decide whether E[P] stays bounded "
                  "(the losses are correlated); see filter_stability (rho(Lambda) rho(A)^2 < 1 is necessary)")


def _chain_estimation(system: System) -> tuple[dict[str, Any], list[str]]:
    """The "estimation" head behind Gilbert-Elliott sensor links (sensing.markov_bounds): whether E[P] stays
    bounded (proved either way, or undecided) and the stationary Markov bounds on tr E[P^-]."""
    sensor = system.sensor
    out: dict[str, Any] = {"gamma": sensor.gamma.tolist(), "groups": [list(g) for g in sensor.groups],
                           "critical_gamma": {"lower": None, "upper": None, "exact": False, "reason": CHAIN_CRITICAL}}
    try:
        fs = filter_stability(system.A, system.noise_cov, sensor)
        bounds = markov_covariance_bounds(system.A, system.noise_cov, sensor)
    except InputError as err:                      # too many joint chain states for the coupled equations
        out["error_covariance_trace"] = {"lower": None, "upper": None, "reason": str(err)}
        out["filter_stability"] = {"bounded": None, "reason": str(err)}
        return out, [f"Gilbert-Elliott sensor links: not analysed: {err}"]
    out["error_covariance_trace"] = {**bounds.to_dict(), "of": "the stationary E[P(k+1|k)] of the TCP-like filter "
                                                               "(Markov bounds)"}
    out["filter_stability"] = fs.to_dict()
    return out, [f"Gilbert-Elliott sensor links (long-run rates {np.round(sensor.gamma, 6).tolist()}): E[P-] "
                 f"{fs.reason}",
                 f"tr E[P-] (stationary, TCP-like filter): [{_num(bounds.trace_lower)}, {_num(bounds.trace_upper)}]"]


def _refused(system: System) -> str | None:
    """Why the sensor analysis does not apply to this (valid) file, or None; the caller reports the reason instead
    of failing."""
    try:
        require_sensor(system, chains=True)
    except InputError as err:
        return str(err)
    return None


def estimated_law(system: System, gain: np.ndarray, protocol: str, law: str) -> dict[str, Any]:
    """One law's exact stationary loop on the protocol's estimate, as JSON (cost null with a reason; ``basis``
    "loop")."""
    try:
        loop = estimated_loop(system, gain, protocol, law)
    except InputError as err:            # e.g. a non-stationary or Gilbert-Elliott actuator channel
        return {"law": law, "protocol": protocol, "cost": None, "basis": "loop", "stable": None,   # no verdict
                "reason": str(err)}
    entry = loop.to_dict()
    entry.pop("gain")
    entry["cost"] = entry.pop("average_stage_cost")
    entry["basis"] = "loop"           # the law run for ever: its stationary average stage cost
    return entry


def _verdict_text(stable: bool | None) -> str:
    """A sensor-loop verdict in text: proved either way, or "undecided" (JSON null)."""
    return "undecided" if stable is None else ("mean-square stable" if stable else "NOT stable")


def _law_text(entry: dict[str, Any]) -> str:
    if entry.get("cost") is None:
        why = entry.get("reason", "").removeprefix("undecided: ")
        return f"{_verdict_text(entry.get('stable'))}, loop cost n/a ({why})"
    # control_part is tr(P Sigma_W) of the DP (the full-state optimum) whatever the law; estimation_part,
    # E[(u + K_dp x)' H (u + K_dp x)], is the rest: the estimation error's cost, and for a law other than the DP law
    # on the TCP-like estimate also the law's excess over the DP law
    rest = (f"estimation {_num(entry.get('estimation_part'))}" if (entry.get("law"), entry.get("protocol")) ==
            ("dp", "tcp") else f"the rest {_num(entry.get('estimation_part'))} (estimation and the law's excess over "
            "the DP law)")
    return (f"loop's average stage cost {_num(entry['cost'])} = full-state DP optimum "
            f"{_num(entry.get('control_part'))} + {rest}; "
            + _verdict_text(entry["stable"])
            + f" (radius of (xhat, e) {_num(entry.get('spectral_radius'))})")


def protocol_entry(system: System, protocol: str, gain: np.ndarray) -> tuple[dict[str, Any], str]:
    """The paper's receding-horizon law of ``protocol`` on that protocol's estimate, for solve's protocol block."""
    entry = estimated_law(system, gain, protocol, protocol)
    note = ("" if protocol == "tcp" else " (certainty equivalence on the UDP estimate: not optimal)")
    return entry, note.strip(" ()") + (": " if note else "") + _law_text(entry)


def simulate_section(system: System, laws: tuple[str, ...], samples: int, steps: int,
                     seed: int) -> tuple[dict[str, Any], list[str]]:
    """``simulate --closed-loop``'s "estimated_state": each law ("dp" and "tcp" on the TCP-like estimate, "udp" on
    the UDP-like one) sampled with the time-varying Kalman filter (exact cost null, with the reason) and with the
    stationary gains (exact cost from sensing.loop). O(laws samples steps (2^g + n^3))."""
    refused = _refused(system)
    if refused is not None:
        return {"reason": refused}, [f"with the estimated state: not run: {refused}"]
    out: dict[str, Any] = {}
    lines = ["with the estimated state (the sensor's links; the runs above measure the full state):"]
    for law in laws:
        protocol = "udp" if law == "udp" else "tcp"
        if law == "dp":
            try:
                gain = dp_riccati(system).gain
            except NumericalError as err:
                out[law] = {"reason": str(err)}
                lines.append(f"  DP law: no law: {err}")
                continue
        else:
            gain = closed_form(system, law).gain
        out[law] = {}
        for name in ("kalman", "stationary"):
            try:
                run = simulate_estimated(system, gain, protocol, name, samples=samples, steps=steps, seed=seed,
                                         law=law)
            except InputError as err:
                if err.field not in ("sensor.gamma", "sensor.model"):      # no stationary gains: the reason
                    raise
                out[law][name] = {"reason": str(err)}
                continue
            out[law][name] = {**run.to_dict(), "basis": "loop"}       # the law's loop on the estimate
            lines += _run_lines(f"{law.upper() if law != 'dp' else 'DP'} law, {protocol.upper()}-like estimate, "
                                f"{name} filter", run)
        kalman = out[law].get("kalman", {})
        stationary = out[law].get("stationary", {})
        if "stable" in stationary:
            stable, why = stationary["stable"], stationary.get("reason", "")
        else:      # no stationary gains, or Gilbert-Elliott links: the verdict estimated_loop proves, if any
            try:
                loop = estimated_loop(system, gain, protocol, law)
                stable, why = loop.stable, loop.reason
            except InputError as err:             # e.g. a non-stationary actuator channel: no verdict
                stable, why = None, str(err)
        out[law].update({
            "mean_stage_cost": kalman.get("mean_stage_cost"), "stderr": kalman.get("stderr"),
            "averaged_steps": kalman.get("averaged_steps"),
            **({"stderr_reason": kalman["stderr_reason"]} if kalman.get("stderr_reason") else {}),
            "exact_stage_cost": None, "exact_reason": kalman.get("reason", ""), "basis": "loop",
            "stable": stable, "stable_reason": why,
        })
        lines.append(f"  {law.upper() if law != 'dp' else 'DP'} law: " + _verdict_text(stable)
                     + (f" ({why.removeprefix('undecided: ')})" if why else ""))
    return out, lines


def _run_lines(label: str, run: EstimatedRun) -> list[str]:
    """One estimated-state run in text: the sample over its window from x0 beside the exact value on that same
    window (its z-score) where there is one, then the stationary cost (the law run for ever: another window), each
    named; the reason for a withheld error bar below."""
    first, last = run.averaged_steps
    spread = "" if run.stderr_reason else f" +- {_num(run.stderr, 3)}"
    sample = f"{label}: mean stage cost {_num(run.mean_stage_cost)}{spread} over steps {first}..{last} from x0"
    if np.isfinite(run.exact_window_cost):
        z = f" (z = {_num(run.z, 3)})" if np.isfinite(run.z) else ""
        sample += f", exact {_num(run.exact_window_cost)} on those steps{z}"
    if run.filter == "stationary":
        stationary = "inf" if run.exact_stage_cost == np.inf else _num(run.exact_stage_cost)
        rest = f"stationary cost (the law run for ever) {stationary} [basis: loop]" + (
            f" ({run.reason})" if run.reason else "")
    else:
        rest = f"no exact value ({run.reason})"
    lines = [f"  {sample} [basis: loop]; {rest}"]
    return lines + ([f"    ({run.stderr_reason})"] if run.stderr_reason else [])


def region_section(system: System, known: Sequence[CriticalPoint] = ()) -> tuple[dict[str, Any], list[str]]:
    """``region``'s "sensor": TCP-like, the thresholds separate (the filter's critical rate along the file's gamma
    and the DP's critical mu along the file's mu); UDP-like, the coupled map is sensing.loop's radius on a grid
    (``sensor_grid``). ``known``: critical points already found at the default tolerance (the region map's);
    the DP's along the file's mu direction is taken from them when there, not bisected again (the same call,
    the same number). O(critical_gamma + critical_mu)."""
    refused = _refused(system)
    if refused is not None:
        return {"reason": refused}, [f"sensor: not computed: {refused}"]
    sensor = system.sensor
    if sensor.channel is not None:
        return _chain_region(system, known)
    direction = sensor.gamma / sensor.gamma.max() if sensor.gamma.max() > 0 else np.ones(sensor.g)
    cg = critical_gamma(system.A, sensor, direction)
    t_mu, why = _dp_critical_mu(system, known)
    out = {"tcp": {"critical_gamma": cg.to_dict(), "critical_mu_dp": finite_or_none(t_mu), "reason": why,
                   "rule": "stable iff gamma = t d with t above the critical rate and mu in the DP's region "
                           "(separation: the estimation error does not depend on the control)"}}
    lines = [f"sensor, TCP-like (separate thresholds): gamma along d = {np.round(direction, 6).tolist()} needs "
             f"t in [{_num(cg.lower)}, {_num(cg.upper)}]" + (" (exact)" if cg.exact else "")
             + f"; the DP law needs mu = t mu_file / max with t > {_num(t_mu)}"]
    return out, lines


def _dp_critical_mu(system: System, known: Sequence[CriticalPoint] = ()) -> tuple[float | None, str]:
    mu = system.mu_schedule[0]
    direction = mu / mu.max() if mu.max() > 0 else None
    for point in known:        # critical_mu(system, "dp", direction) is critical_point(system, "dp", direction)
        if point.law == "dp" and direction is not None and np.array_equal(point.direction, direction):
            return float(point.t), ""
    try:       # a file's mu of zeros has no direction: refused as such (not the default direction, all ones)
        return float(critical_mu(system, "dp", mu if direction is None else direction).t), ""
    except (NumericalError, InputError) as err:
        return None, str(err)


def _chain_region(system: System, known: Sequence[CriticalPoint] = ()) -> tuple[dict[str, Any], list[str]]:
    """``region``'s "sensor" behind Gilbert-Elliott sensor links: TCP-like, the filter's verdict (proved, or
    undecided) beside the DP's critical mu; the coupled (gamma, mu) map is not derived (its ``reason``)."""
    try:
        fs: dict[str, Any] = filter_stability(system.A, system.noise_cov, system.sensor).to_dict()
    except InputError as err:
        fs = {"bounded": None, "reason": str(err)}
    t_mu, why = _dp_critical_mu(system, known)
    out = {"reason": "the coupled (gamma, mu) map behind Gilbert-Elliott sensor links is not derived "
                     "(no --sensor-grid)",
           "tcp": {"filter_stability": fs, "critical_mu_dp": finite_or_none(t_mu), "reason": why,
                   "rule": "needs E[P] bounded (filter_stability) and mu in the DP's region (separation: the "
                           "estimation error does not depend on the control)"}}
    return out, [f"sensor (Gilbert-Elliott), TCP-like: E[P-] {fs['reason']}; the DP law needs "
                 f"mu = t mu_file / max with t > {_num(t_mu)}; {out['reason']}"]


def coupled_grid(system: System, grid: int) -> dict[str, Any]:
    """The TCP-like and UDP-like loops' verdicts on a grid of (gamma scale, mu scale) in (0, 1]^2: the paper's law
    re-designed at each mu on its protocol's stationary filter (sensing.loop.loop_map). O(grid^2 (2n)^6)."""
    ts = np.linspace(1.0 / grid, 1.0, grid)
    out: dict[str, Any] = {"gamma_scale": ts.tolist(), "mu_scale": ts.tolist()}
    for protocol, (radius, _) in loop_map(system, ts, ts, ("tcp", "udp")).items():
        # nan (gains undetermined, or gamma between the critical-rate bounds) and a radius within the margin of 1:
        # null, no verdict; inf only where proved unbounded (sensing.loop.loop_map)
        verdicts = [[loop_verdict(float(r)) for r in row] for row in radius]
        out[protocol] = {"radius": [[finite_or_none(v) for v in row] for row in radius], "stable": verdicts,
                         "stable_share": float(np.mean([[v is True for v in row] for row in verdicts])),
                         "undecided_share": float(np.mean([[v is None for v in row] for row in verdicts]))}
    return out
