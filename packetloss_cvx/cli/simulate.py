"""``packetloss-cvx simulate FILE``: sampled costs against their exact expectations, open and closed loop."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..model.system import loop_weights
from ..montecarlo.markov import EXACT_PLAN
from ..montecarlo.simulate import LAWS, simulate
from ..results import Simulation
from ..safeio import atomic_write, check_output_file, figure_path, save_figure
from .actuator_section import actuator_strategies, simulate_actuator_section
from .common import (
    CommandResult,
    check_dead_flags,
    check_figure_format,
    constraints_of,
    figure_dpi,
    figure_file,
    mpc_samples_of,
    progress_of,
    system_of,
)
from .sensing_section import simulate_section

__all__ = ["run"]

#: runs whose trajectories --save keeps (the curves cover every run)
SAVED_RUNS = 1000
#: why a TCP-like plan's exact cost exceeds the protocol's J* (docs/claims.md, expected-cost-tcp); printed when
#: the two differ by more than TCP_GAP_RTOL relative (they agree when every mu_i is 0 or 1) on a Bernoulli channel
#: (under a Gilbert-Elliott chain the correlated losses add to the gap, for both protocols)
TCP_GAP_NOTE = ("    (not a bug: the paper's TCP-like J* assumes the controller knows which packets will arrive, so it "
                "leaves out the loss variance U'Vbar Omega_d (I - Vbar) U = {gap} that a plan applied whatever the "
                "losses pays; see the audit's expected-cost-tcp finding in docs/claims.md, or run "
                "`packetloss-cvx audit --claim expected-cost-tcp`)")
TCP_GAP_RTOL = 1e-9
FLAGS = {"samples": "--samples", "steps": "--steps", "seed": "--seed", "law": "--law", "mu_schedule": "--closed-loop"}


def run(args: argparse.Namespace) -> CommandResult:
    """Exit 0 whatever the loops do: an unstable closed loop is a result (``"stable": false``).

    Examples
    --------
    One step of x' = x + v u from x0 = 1, mu = 0.5: the TCP-like plan u = -2/3 realises
    E[(1 + v u)^2 + v u^2] = 1 + 2 mu u + 2 mu u^2 = 7/9 (its formula `J*_tcp` = 2/3 leaves out the loss
    variance); the UDP-like plan u = -1/2 realises its `J*_udp` = 3/4.

    >>> import tempfile
    >>> from pathlib import Path
    >>> from packetloss_cvx.model.files import save_system
    >>> from packetloss_cvx.model.system import System
    >>> from packetloss_cvx.cli.parser import build_parser
    >>> s = System(A=[[1.0]], B=[[1.0]], horizon=1, state_weight=[1.0], input_weight=[1.0], mu=[0.5], x0=[1.0])
    >>> folder = tempfile.TemporaryDirectory()
    >>> path = str(save_system(s, Path(folder.name) / "scalar.toml"))
    >>> result = run(build_parser().parse_args(["simulate", path, "--samples", "200"]))
    >>> tcp, udp = result.data["tcp"]["open_loop"], result.data["udp"]["open_loop"]
    >>> bool(np.isclose(tcp["exact"], 7 / 9) and np.isclose(udp["exact"], 0.75)), abs(tcp["z"]) < 4, result.code
    (True, True, 0)
    >>> folder.cleanup()
    """
    system = system_of(args)
    strategies = actuator_strategies(getattr(args, "actuator", None), system)     # refused before any work
    constraints = constraints_of(args, system)     # the file's [constraints] table and its overrides, or None
    check_dead_flags(args)      # --mpc-samples without a table, --format/--dpi/--yscale without --plot
    mpc_samples = mpc_samples_of(args)
    if args.closed_loop or (constraints is not None and mpc_samples):   # refused before the open loop runs
        loop_weights(system, "cost.state_weights")
    if constraints is not None and mpc_samples:
        if system.channel is None and not system.is_stationary:
            raise InputError("--mu-schedule", "the constrained loop (a [constraints] table) runs for ever over one "
                                              "channel: it needs one mu per actuator, not a schedule; give --mu, or "
                                              "--mpc-samples 0 to skip the loop")
    if constraints is not None and mpc_samples and args.law == "dp":
        raise InputError("--law", "the constrained loop runs the protocols' programs: --law tcp, udp or all "
                                  "(or --mpc-samples 0 to skip it)")
    if (getattr(args, "dask", None) is not None or getattr(args, "threads", 1) != 1) and (constraints is None
                                                                                       or not mpc_samples):
        raise InputError("--dask" if getattr(args, "dask", None) is not None else "--threads",
                         "spreads the constrained loop's runs: give FILE a [constraints] table (or --u-max, ...) "
                         "and --mpc-samples >= 1")
    if getattr(args, "workers", None) is not None and getattr(args, "dask", None) != "local":
        raise InputError("--workers", "applies to --dask local only")
    constrained = constraints is not None and bool(mpc_samples)
    if strategies and not args.closed_loop and not constrained:
        raise InputError("--actuator", "the actuator's strategy acts in the closed loop: add --closed-loop, or give "
                                       "FILE a [constraints] table (or --u-max, ...) for the constrained loop")
    if strategies and system.channel is not None and args.closed_loop:
        raise InputError("--actuator", "behind a Markov channel simulate's laws read the channel's belief, not "
                                       "u = -K x: use solve --actuator (the plug-in laws, exact under the chain), or "
                                       "--mu for the Bernoulli twin (without --closed-loop, a [constraints] table's "
                                       "constrained loop runs each strategy behind the chain)")
    laws = LAWS if args.law == "all" else (args.law,)
    if not args.closed_loop:
        laws = tuple(law for law in laws if law != "dp")
    keep = SAVED_RUNS if args.save and args.closed_loop else 0
    force = getattr(args, "force", False)
    plot = figure_file(args, args.plot) if args.plot else None      # `--plot loop --format pdf` writes loop.pdf
    if plot:
        check_figure_format(plot, "--plot")      # before the sampling, not after it
        check_output_file(figure_path(plot), "--plot", force)
    try:
        sim = simulate(system, args.samples, steps=args.steps, seed=args.seed, closed_loop=args.closed_loop,
                       laws=laws, keep=keep, progress=progress_of(args))
    except InputError as err:
        raise err.renamed(FLAGS.get(err.field, err.field)) from None
    if args.save:
        _save(sim, args.save, force)
    if args.plot:
        if not sim.closed_loop:
            raise InputError("--plot", "the figure shows the closed loop: add --closed-loop")
        from ..plots import plot_closed_loop  # matplotlib (0.2-0.7 s) only where a figure is asked for
        figure = plot_closed_loop(sim, yscale=getattr(args, "yscale", None) or "linear",
                                  title=f"{system.name or 'system'}: closed loop of each law")
        save_figure(figure, plot, overwrite=force, field="--plot", dpi=figure_dpi(args))
    data, text = sim.to_dict(), _text(system.name or args.file, sim)
    for p, entry in data.items():      # what "formula" is: the paper's J* (the exact minimiser's: under the chain)
        if "open_loop" in entry:
            entry["open_loop"]["formula_basis"] = "attainable" if p == EXACT_PLAN else "paper"
            entry["open_loop"]["basis"] = "realised"      # mean and exact: the plan's realised cost
        if "closed_loop" in entry:
            entry["closed_loop"]["basis"] = "loop"
            entry["closed_loop"]["averaged_steps"] = [0, sim.steps - 1]      # sample and exact: the whole window
    if strategies and args.closed_loop:     # the laws' loops when the actuator zeroes, holds or plays the plan
        data["actuator"], more = simulate_actuator_section(system, laws, strategies, args.steps, args.samples,
                                                           args.seed)
        text = "\n".join([text, *more])
    if constrained:     # the [constraints] table: the constrained receding-horizon loop (per strategy, --actuator)
        from .mpc_section import constrained_loop_section  # cvxpy (1.5 s to import) only where a program is solved

        protocols = ("tcp", "udp") if args.law == "all" else (args.law,)
        data["constrained_loop"], more = constrained_loop_section(system, constraints, protocols, mpc_samples,
                                                                  args.steps, args.seed, progress_of(args),
                                                                  threads=getattr(args, "threads", 1),
                                                                  dask=getattr(args, "dask", None),
                                                                  workers=getattr(args, "workers", None),
                                                                  strategies=strategies)
        text = "\n".join([text, *more])
    if system.sensor is not None and args.closed_loop:     # lossy sensor links
        data["estimated_state"], more = simulate_section(system, laws, args.samples, args.steps, args.seed)
        text = "\n".join([text, *more])
    return CommandResult(data, text)


def _save(sim: Simulation, path: str, force: bool) -> None:
    if not path.endswith(".npz"):
        raise InputError("--save", f"expected a FILE.npz, found {path!r}")
    arrays: dict[str, np.ndarray] = {"samples": np.array(sim.samples), "steps": np.array(sim.steps),
                                     "seed": np.array(sim.seed), "laws": np.array(list(sim.closed_loop))}
    if sim.trajectories is not None:
        arrays["trajectories"] = sim.trajectories
    for law, r in sim.closed_loop.items():
        arrays.update({f"{law}_state_norm_mean": r.state_norm_mean, f"{law}_state_norm_std": r.state_norm_std,
                       f"{law}_stage_cost_mean": r.stage_cost_mean})
    with atomic_write(Path(path), overwrite=force, field="--save") as handle:
        np.savez_compressed(handle, **arrays)


def _num(value: float, digits: int = 6) -> str:
    return f"{value:.{digits}g}" if np.isfinite(value) else "n/a"


def _text(name: str, sim: Simulation) -> str:
    bursty = sim.channel != "bernoulli"
    lines = [f"{name}: {sim.samples} sampled runs, seed {sim.seed}"
             + (f" (the {'Gilbert-Elliott' if sim.channel == 'gilbert-elliott' else 'Markov'} chain sampled per run; "
                "exact values under the chain)" if bursty else "")]
    for p, c in sim.open_loop.items():
        label = "exact minimiser's plan" if p == EXACT_PLAN else f"{p.upper()}-like {'plug-in ' if bursty else ''}plan"
        if c.reason:
            lines.append(f"  {label}, open loop: not run: {c.reason}")
            continue
        formula = "its J* (exact under the chain, attainable)" if p == EXACT_PLAN else "the paper's J*" + (
            " with the plug-in mu_t" if bursty else "")
        spread = "" if c.stderr_reason else f" +- {_num(c.stderr, 3)}"
        z = "" if c.stderr_reason else f" (z = {_num(c.z, 3)})"
        lines.append(f"  {label}, open loop: its cost sampled {_num(c.mean)}{spread}, exact "
                     f"{_num(c.exact)}{z} [basis: realised]; {formula} = {_num(c.formula)}")
        if c.stderr_reason:
            lines.append(f"    ({c.stderr_reason})")
        if p == "tcp" and not bursty and not np.isclose(c.exact, c.formula, rtol=TCP_GAP_RTOL, atol=0.0):
            lines.append(TCP_GAP_NOTE.format(gap=_num(c.exact - c.formula)))
    for law, r in sim.closed_loop.items():
        label = ("mode-dependent law" if bursty else "DP optimum") if law == "dp" else f"{law.upper()}-like law"
        if r.reason:
            lines.append(f"  {label}, closed loop: no law: {r.reason}")
            continue
        radius = "MJLS second-moment" if bursty else "second-moment"
        verdict = (f"mean-square stable ({radius} spectral radius {_num(r.spectral_radius)})" if r.stable else
                   f"NOT mean-square stable ({radius} spectral radius {_num(r.spectral_radius)})"
                   if np.isfinite(r.spectral_radius) else "mean-square stability not decided")
        spread = f" +- {_num(r.stderr, 3)}" if not r.stderr_reason else ""
        lines.append(f"  {label}, closed loop over {sim.steps} steps: mean stage cost {_num(r.mean_stage_cost)}"
                     f"{spread} over steps 0..{sim.steps - 1} from x0, exact {_num(r.exact_stage_cost)} on those steps "
                     f"[basis: loop]; {verdict}")
        for extra in (r.stderr_reason, r.exact_reason, r.note):
            if extra:
                lines.append(f"    ({extra})")
        if not r.stderr_reason and r.stderr == 0.0:
            lines.append("    (zero spread: every run has the same cost (no random loss or noise changes this loop's "
                         "run), so the sample is the loop's cost itself)")
        # rare runs carry the cost only where the losses are random: an unstable loop with an error bar has none
        if not r.stable and np.isfinite(r.spectral_radius) and r.stderr_reason:
            lines.append("    (a mean-square unstable loop's expected cost is carried by rare runs: its sampled mean "
                         "and standard error can fall far below the exact value)")
    if "dp" in sim.closed_loop and not bursty and not sim.closed_loop["dp"].reason:
        lines.append("  (the DP law is optimal for the cost over an unbounded horizon; over a window of "
                     f"{sim.steps} steps from x0 a law that is not stable can still have a lower loop cost)")
    return "\n".join(lines)
