"""Probes, not capabilities: two schedules for one stabilisable-set iteration over M-mode chains, each put in place
of the chain iteration (chain_radius) to measure what it gains and loses, on chains and at one mode.

- ``bernoulli``: the Bernoulli iteration's schedule (region.homogeneous_riccati: shifted power steps of the
  least-squares Riccati step, handed to an unregularised Kronecker policy iteration after 30 steps, or after 4 where
  they shrink too slowly; balanced where P is graded, kept where its gain's radius is nearer) written for M modes,
  in place of chain_radius's reachable-part eigenpair behind the same controllability split.
- ``chain``: the chain iteration itself with two schedule changes: its first policy iteration at power step 4
  instead of 30, and an unbalanced pass whose P is graded (riccati_map.grading_scale) stopped at the checkpoint, the
  balanced pass redoing it (where the bracket of a graded P cannot close).
- ``one``: one iteration for both, the Bernoulli region functions calling it on one-state chains (each point of a
  batch alone, region.homogeneous_riccati and the modules that import it patched): at M > 1 the chain iteration as
  it is (probe ``chain``'s schedule there fails two CLI chain tests, tests/cli/test_cli_region.py); at
  M = 1 the same power steps (chain_radius._apply's sum of squares, the gains chain_radius._gains) specialised by
  shape: no regularisation, the Bernoulli hand-off at step 4 or 30, the unregularised policy iteration by one
  ``eig`` of the (Kronecker) operator, no bracket and no refinement, lambda R's sum of squares at P, balanced by
  the Bernoulli rule (kept where its gain's radius is nearer its lambda; region._GRADED, the tests' switch, read).

    OPENBLAS_NUM_THREADS=1 PYTHONPATH=$PWD python benchmarks/region_schedule_probe.py [--probe bernoulli|chain|one]
    OPENBLAS_NUM_THREADS=1 python benchmarks/region_schedule_probe.py --probe one --engine [--baseline DIR]

Prints the CPU of the chain cases of benchmarks/region_engine.py (chain memberships under both conventions, the
two_actuator rate map, a critical mean rate) unpatched and probed, their answers' largest relative difference and
the verdicts that change; the chain tests (tests/closedloop/test_markov_region.py, test_chain_certificates.py) run
with the probe installed (``pytest -p region_schedule_probe``); and for ``chain`` the one-mode cases of
region_engine.py against the Bernoulli iteration (CPU ratio, least radii apart, error from the hand value), for
``one`` too. With ``--engine``: region_engine.py's worker cases for the baseline checkout, this one and this one
probed, interleaved rounds, medians (`engine`).
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent.parent


def _step(P, A, B, T, h, delivery):
    """``(K, R(P))`` at M modes: the minimum-norm least-squares gains of the mode Hessians and ``A'E_aA - G_a'K_a``
    (region's step, summed over the next mode)."""
    from packetloss_cvx.closedloop import chain_radius

    H, G = chain_radius._hessians(P, A, B, T, h, delivery)
    m = B.shape[1]
    if not np.all(np.isfinite(H)):
        return np.full((P.shape[0], m, A.shape[0]), np.nan), np.full_like(P, np.nan)
    K = np.linalg.pinv(H, rcond=np.finfo(float).eps * m) @ G
    R = A.T @ np.einsum("ab,bij->aij", T, P) @ A - np.swapaxes(G, -1, -2) @ K
    return K, 0.5 * (R + np.swapaxes(R, -1, -2))


def _total(P):
    return float(np.trace(P, axis1=-2, axis2=-1).sum())


def _power(P, A, B, T, h, delivery, first, steps, watch, floor):
    """Region's shifted power steps ``first .. steps - 1``: (P, how it ended, tr R / tr P where the zero test
    stopped it)."""
    from packetloss_cvx.closedloop.riccati_map import SHIFT, converges_within
    from packetloss_cvx.tolerances import RICCATI_RTOL

    last = np.inf
    for step in range(first, steps):
        _, R = _step(P, A, B, T, h, delivery)
        lam = _total(R)
        if not (np.isfinite(lam) and lam > floor * _total(P)):
            return P, "zero", (lam / _total(P) if np.isfinite(lam) else None)
        P_next = (R / lam + SHIFT * P) / (1.0 + SHIFT)
        moved = float(np.linalg.norm(P_next - P))
        P = P_next
        if moved <= RICCATI_RTOL:
            return P, "done", None
        if watch and step + 1 == 4 and not converges_within(np.array([moved]), np.array([last]), steps - step - 1)[0]:
            return P, "slow", None
        last = moved
    return P, "steps", None


def _policy(P, A, B, channel, T, h, delivery, gains=None):
    """Region's policy iteration on the coupled operator (unregularised): (P found, whether it moved). ``gains``: the
    gain step P -> K (default: this probe's `_step`)."""
    from packetloss_cvx.closedloop.mjls import second_moment_operator
    from packetloss_cvx.closedloop.riccati_map import POLICY_STEPS
    from packetloss_cvx.tolerances import CERTIFICATE_RTOL, RICCATI_RTOL

    M, n = P.shape[0], A.shape[0]
    best, last, moved = P.copy(), np.inf, False
    for _ in range(POLICY_STEPS):
        K = _step(P, A, B, T, h, delivery)[0] if gains is None else gains(P)
        if not np.all(np.isfinite(K)):
            break
        operator = second_moment_operator(A, B, channel, K, delivery).T
        if not np.all(np.isfinite(operator)):
            break
        vals, vecs = np.linalg.eig(operator)
        top = int(np.argmax(vals.real))
        lam = float(vals[top].real)
        V = vecs[:, top].real.reshape(M, n, n)
        V = 0.5 * (V + np.swapaxes(V, -1, -2))
        trace = _total(V)
        if not (np.isfinite(lam) and trace != 0.0):
            break
        P_next = V / trace
        if lam <= 0.0 or min(float(np.linalg.eigvalsh(p)[0]) for p in P_next) < -CERTIFICATE_RTOL:
            break
        settled = lam >= last * (1.0 - RICCATI_RTOL)
        if not settled or lam <= last:
            best, moved = P_next, True
        if settled:
            break
        last, P = lam, P_next
    return best, moved


def _fixed(P, A, B, T, h, delivery):
    from packetloss_cvx.tolerances import RICCATI_RTOL

    _, R = _step(P, A, B, T, h, delivery)
    lam = _total(R)
    return bool(np.isfinite(lam) and lam > 0 and np.linalg.norm(R / lam - P / _total(P)) <= RICCATI_RTOL)


def _iterate(A, B, channel, T, h, delivery, start=None):
    """Region's `_iterate` at M modes, one point: (lambda, P, K)."""
    from packetloss_cvx.closedloop import chain_radius
    from packetloss_cvx.linalg import controllable_split
    from packetloss_cvx.tolerances import LEAST_RADIUS_ATOL

    M, n = len(h), A.shape[0]
    P = np.repeat(np.eye(n)[None] / (n * M), M, axis=0) if start is None else start
    floor = LEAST_RADIUS_ATOL * float(np.linalg.norm(A, 2)) ** 2
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        P, ended, zeroed = _power(P, A, B, T, h, delivery, 0, 30, True, floor)
        if ended in ("steps", "slow"):
            found, moved = _policy(P, A, B, channel, T, h, delivery)
            moved = moved and (ended != "slow" or _fixed(found, A, B, T, h, delivery))
            if moved:
                P = found
            elif ended == "slow":
                P, ended, zeroed = _power(P, A, B, T, h, delivery, 4, 30, False, floor)
                if ended == "steps":
                    P = _policy(P, A, B, channel, T, h, delivery)[0]
        K, _ = _step(P, A, B, T, h, delivery)
        lam = chain_radius._apply(P, A, B, T, h, delivery, 0.0)[1]
    if zeroed is not None:
        lam = float(np.clip(zeroed, 0.0, floor))
    always = np.all(h == 1.0, axis=0)
    if np.any(always) and controllable_split(A, B[:, always]).nc == n:
        lam = 0.0
    return lam, P, K


def _gap(A, B, channel, delivery, lam, P, K):
    from packetloss_cvx.closedloop.mjls import mean_square_radius
    from packetloss_cvx.errors import NumericalError

    try:
        return abs(mean_square_radius(A, B, channel, K, delivery) - lam) if np.all(np.isfinite(K)) else np.inf
    except NumericalError:
        return np.inf


def balanced_eigenpair(A, B, channel, T, h, delivery):
    """Region's `_graded` at M modes: the iteration, and again on the plant scaled by the grading of P, kept where
    its gain's radius is nearer its lambda."""
    from packetloss_cvx.closedloop.riccati_map import GRADED, grading_scale

    best, gap = _iterate(A, B, channel, T, h, delivery), None
    for _ in range(2):
        D = grading_scale(best[1], GRADED)
        if D is None:
            break
        lam, P, K = _iterate(A * D[None, :] / D[:, None], B / D[:, None], channel, T, h, delivery,
                             D[None, :, None] * best[1] * D[None, None, :])
        found = (lam, P / D[None, :, None] / D[None, None, :], K / D[None, None, :])
        gap = _gap(A, B, channel, delivery, *best) if gap is None else gap
        found_gap = _gap(A, B, channel, delivery, *found)
        if not found_gap < max(gap, 1e-7 * abs(found[0])):
            break
        best, gap = found, found_gap
    return best


def _one_power(P, A, B, T, h, delivery, first, steps, watch):
    """The chain iteration's power steps (chain_radius._power) with the one-mode specialisation: at M = 1 no
    regularisation (eps = 0: no mode can go unweighted) and, with ``watch``, the Bernoulli hand-off at step 4 of a
    point whose steps shrink too slowly to settle by ``steps`` (ended "slow")."""
    from packetloss_cvx.closedloop import chain_radius
    from packetloss_cvx.closedloop.riccati_map import SHIFT, converges_within
    from packetloss_cvx.tolerances import COUPLED_POLICY_REGULARISATION, RICCATI_RTOL

    M = P.shape[0]
    plain = M * P.shape[1] + 1
    lam, moved, last = float("nan"), float("inf"), float("inf")
    for step in range(first, steps):
        regularise = M > 1 and step >= plain and np.isfinite(lam) and lam > 0
        R, lam, zero = chain_radius._apply(P, A, B, T, h, delivery,
                                           COUPLED_POLICY_REGULARISATION * lam if regularise else 0.0)
        if zero and step < plain:
            return P, 0.0, "zero", moved
        total = _total(R)
        if not (np.isfinite(lam) and lam > 0 and np.isfinite(total)):
            return P, lam, "stopped", moved
        shift = SHIFT if step >= plain else 0.0
        P_next = (R / total + shift * P) / (1.0 + shift)
        moved = float(np.linalg.norm(P_next - P))
        P = P_next
        if moved <= RICCATI_RTOL and step >= plain:
            return P, lam, "stopped", moved
        if watch and step + 1 == 4 and step >= plain and not converges_within(
                np.array([moved]), np.array([last]), steps - step - 1)[0]:
            return P, lam, "slow", moved
        last = moved
    return P, lam, "steps", moved


def _one_policy(P, A, B, channel, T, h, delivery):
    """The policy iteration at M = 1: unregularised, the Perron eigenvector of the operator (the Kronecker matrix at
    one mode) by one ``eig`` a step (region's), the gains the chain's minimiser (chain_radius._gains from 0):
    (P found, whether it moved). `_policy` with that gain step."""
    from packetloss_cvx.closedloop import chain_radius

    M, n, m = P.shape[0], A.shape[0], B.shape[1]
    return _policy(P, A, B, channel, T, h, delivery,
                   gains=lambda Q: chain_radius._gains(Q, A, B, T, h, delivery, np.zeros((M, m, n))))


def _one_fixed(P, A, B, T, h, delivery):
    from packetloss_cvx.closedloop import chain_radius
    from packetloss_cvx.tolerances import RICCATI_RTOL

    R, lam, _ = chain_radius._apply(P, A, B, T, h, delivery, 0.0)
    total = _total(R)
    return bool(np.isfinite(lam) and lam > 0 and np.linalg.norm(R / total - P / _total(P)) <= RICCATI_RTOL)


def one_reachable(A, B, channel, T, h, delivery, start=None):
    """The one iteration's reachable-pair eigenpair: at M > 1 the chain iteration (chain_radius's); at M = 1 the same
    power steps unregularised, handed to the unregularised Kronecker policy iteration at step 4 (slow) or 30, one
    pass, lambda R's sum of squares at P (no bracket, no refinement: no mode can go unweighted at one mode)."""
    from packetloss_cvx.closedloop import chain_radius

    if len(h) > 1:
        return _CHAIN_REACHABLE(A, B, channel, T, h, delivery)
    n, m = A.shape[0], B.shape[1]
    P = np.eye(n)[None] / n if start is None else start
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        P, lam, ended, _ = _one_power(P, A, B, T, h, delivery, 0, 30, True)
        if ended == "zero":
            P, _, _, _ = _one_power(P, A, B, T, h, delivery, n + 1, n + 31, False)
            return 0.0, P, chain_radius._gains(P, A, B, T, h, delivery, np.zeros((1, m, n)))
        if ended in ("steps", "slow"):
            found, moved = _one_policy(P, A, B, channel, T, h, delivery)
            moved = moved and (ended != "slow" or _one_fixed(found, A, B, T, h, delivery))
            if moved:
                P = found
            elif ended == "slow":
                P, _, ended, _ = _one_power(P, A, B, T, h, delivery, 4, 30, False)
                if ended == "steps":
                    P = _one_policy(P, A, B, channel, T, h, delivery)[0]
        K = chain_radius._gains(P, A, B, T, h, delivery, np.zeros((1, m, n)))
        lam = chain_radius._apply(P, A, B, T, h, delivery, 0.0)[1]
    always = np.all(h == 1.0, axis=0)
    if np.any(always):
        from packetloss_cvx.linalg import controllable_split
        if controllable_split(A, B[:, always]).nc == n:
            lam = 0.0
    return lam, P, K


def one_balanced(A, B, channel, T, h, delivery):
    """The one iteration's balancing: at M > 1 the chain's (kept where the exact radius of its gains is smaller); at
    M = 1 the same scaling, two passes at most, kept where its gain's radius is nearer its lambda (region's rule)."""
    from packetloss_cvx.closedloop import region
    from packetloss_cvx.closedloop.riccati_map import grading_scale

    if len(h) > 1:
        return _CHAIN_BALANCED(A, B, channel, T, h, delivery)
    best, gap = one_reachable(A, B, channel, T, h, delivery), None
    for _ in range(2):      # region._GRADED: the tests' switch (0.0: the unbalanced iteration)
        D = grading_scale(best[1], region._GRADED) if best[0] > 0 else None
        if D is None:
            break
        lam, P, K = one_reachable(A * D[None, :] / D[:, None], B / D[:, None], channel, T, h, delivery,
                                  D[None, :, None] * best[1] * D[None, None, :])
        found = (lam, P / D[None, :, None] / D[None, None, :], K / D[None, None, :])
        gap = _gap(A, B, channel, delivery, *best) if gap is None else gap
        found_gap = _gap(A, B, channel, delivery, *found)
        if not found_gap < max(gap, 1e-7 * abs(found[0])):
            break
        best, gap = found, found_gap
    return best


def one_homogeneous_riccati(A, B, mu, start=None):
    """region.homogeneous_riccati through the one iteration: each point of the batch as a one-state chain (its
    ``start`` not used)."""
    from packetloss_cvx.closedloop.chain_radius import homogeneous_coupled_riccati
    from packetloss_cvx.errors import NumericalError
    from packetloss_cvx.model.channel import MarkovChannel

    mu = np.asarray(mu, dtype=float)
    single = mu.ndim == 1
    mus = mu.reshape(-1, B.shape[1])
    n, m = B.shape
    lam, P, K = np.empty(mus.shape[0]), np.empty((mus.shape[0], n, n)), np.empty((mus.shape[0], m, n))
    for g, point in enumerate(mus):
        try:
            lam[g], P_, K_ = homogeneous_coupled_riccati(
                A, B, MarkovChannel(transition=[[[1.0]]] * m, delivery=[[float(x)] for x in point]))
        except NumericalError as err:
            raise NumericalError(f"homogeneous Riccati eigenpair: {err}") from None
        P[g], K[g] = P_[0], K_[0]
    return (float(lam[0]), P[0], K[0]) if single else (lam, P, K)


_CHAIN_REACHABLE = _CHAIN_BALANCED = None


#: the environment variable naming the probe `install` puts in place (read by the pytest plugin too)
PROBE = "REGION_SCHEDULE_PROBE"


def install() -> None:
    """Put the probe named by the environment's REGION_SCHEDULE_PROBE (default "bernoulli") in place."""
    from packetloss_cvx.closedloop import chain_radius
    from packetloss_cvx.closedloop.riccati_map import GRADED, grading_scale
    from packetloss_cvx.tolerances import HOMOGENEOUS_RICCATI_MAX_ITER

    global _CHAIN_REACHABLE, _CHAIN_BALANCED
    probe = os.environ.get(PROBE, "bernoulli")
    if probe == "bernoulli":
        chain_radius._balanced_eigenpair = balanced_eigenpair
        return
    if probe == "one":
        from packetloss_cvx.allocation import stability
        from packetloss_cvx.closedloop import region
        from packetloss_cvx.studies import region_map

        _CHAIN_REACHABLE, _CHAIN_BALANCED = chain_radius._reachable_eigenpair, chain_radius._balanced_eigenpair
        chain_radius._balanced_eigenpair = one_balanced
        for module in (region, stability, region_map):
            module.homogeneous_riccati = one_homogeneous_riccati
        return
    chain_radius._CHECKPOINTS = (4, 30, 90, 270, 810, 2430, HOMOGENEOUS_RICCATI_MAX_ITER)
    power = chain_radius._power

    def graded_stop(P, A, B, T, h, delivery, first, steps):
        P, lam, ended, moved = power(P, A, B, T, h, delivery, first, steps)
        if ended == "steps" and first > 0 and grading_scale(P, GRADED) is not None:
            ended = "stopped"
        return P, lam, ended, moved

    chain_radius._power = graded_stop


def pytest_configure(config) -> None:
    """``pytest -p region_schedule_probe``: the chain tests with the probe installed."""
    install()


def _chain_cases():
    """The chain cases of benchmarks/region_engine.py, each answer as (words, numbers)."""
    from packetloss_cvx import System, load_example
    from packetloss_cvx.closedloop.markov_region import (
        chain_at_rate,
        chain_critical_rate,
        chain_membership,
        chain_rate_map,
    )
    from packetloss_cvx.errors import NumericalError
    from packetloss_cvx.model.channel import GilbertElliott

    out = []
    for seed, A, B, ch in _engine().seeded_chains():
        for delivery in ("next", "current"):
            found = chain_membership(A, B, ch, delivery)
            out.append((f"membership seed {seed} {delivery}", [found.verdict],
                        [found.radius, found.certificate_margin]))
    two = load_example("two_actuator")
    decided, lam = chain_rate_map(two.A, two.B, GilbertElliott(p=[0.3, 0.2], r=[0.4, 0.5]), np.linspace(0, 1, 4))
    out.append(("rate map 4x4 (nan: undecided)", [str(v) for v in decided.ravel()], list(lam.ravel())))
    a, corr = np.array([1.5, 1.2]), np.array([0.2, 0.6])
    ch = chain_at_rate(GilbertElliott(p=(1 - corr) / 2, r=(1 - corr) / 2), [0.5, 0.5])
    s = System(A=np.diag(a), B=np.eye(2), horizon=2, state_weight=[1.0, 1.0], input_weight=[1.0, 1.0], x0=[1.0, 1.0],
               channel=ch)
    try:
        point = chain_critical_rate(s, [1.0, 1.0])
        out.append(("critical mean rate", ["found"], [point.t, point.lower]))
    except NumericalError as err:
        out.append(("critical mean rate", [f"NumericalError: {str(err)[:90]}"], []))
    return out


def _one_mode(reference: dict) -> None:
    """The one-mode cases of region_engine.py through the installed probe against the Bernoulli iteration
    (``reference``: family -> (CPU s, least radii), measured before the probe was installed)."""
    from packetloss_cvx.closedloop.chain_radius import homogeneous_coupled_riccati
    from packetloss_cvx.model.channel import MarkovChannel

    engine = _engine()
    print("| family | Bernoulli ms | probe ms | ratio | max rel diff | rel err from hand (B / probe) |")
    print("|---|---|---|---|---|---|")
    totals = [0.0, 0.0]
    for family, cases in _families(engine).items():
        best, lams = float("inf"), []
        for _ in range(3):
            t0 = time.process_time()
            lams = [homogeneous_coupled_riccati(A, B, MarkovChannel(transition=[[[1.0]]] * len(mu),
                                                                     delivery=[[float(x)] for x in mu]))[0]
                    for A, B, mu, _ in cases]
            best = min(best, time.process_time() - t0)
        cpu, ref = reference[family]
        totals[0] += cpu
        totals[1] += best
        diff = max(0.0 if a == b else abs(a - b) / abs(a) for a, b in zip(ref, lams, strict=True))
        hands = [hand for *_, hand in cases]
        hand = "-" if hands[0] is None else (f"{max(abs(a - h) / h for a, h in zip(ref, hands, strict=True)):.1e} / "
                                             f"{max(abs(a - h) / h for a, h in zip(lams, hands, strict=True)):.1e}")
        print(f"| {family} | {1e3 * cpu:.1f} | {1e3 * best:.1f} | {best / cpu:.2f} | {diff:.1e} | {hand} |")
    print(f"| total | {1e3 * totals[0]:.1f} | {1e3 * totals[1]:.1f} | {totals[1] / totals[0]:.2f} | | |")


def _engine():
    """benchmarks/region_engine.py, loaded by path (its one-mode cases)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("region_engine", HERE / "benchmarks" / "region_engine.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _families(engine) -> dict:
    families: dict[str, list] = {}
    for family, *case in engine._one_mode_cases():
        families.setdefault(family, []).append(case)
    return families


def _bernoulli_reference() -> dict:
    """family -> (CPU s best of 3, least radii) of the Bernoulli iteration on the one-mode cases."""
    from packetloss_cvx.closedloop.region import homogeneous_riccati

    out = {}
    for family, cases in _families(_engine()).items():
        best, lams = float("inf"), []
        for _ in range(3):
            t0 = time.process_time()
            lams = [homogeneous_riccati(A, B, mu)[0] for A, B, mu, _ in cases]
            best = min(best, time.process_time() - t0)
        out[family] = (best, lams)
    return out


def _engine_worker(root: Path, probe: str | None, repeats: int) -> dict:
    """region_engine.py's worker cases in a fresh process importing ``root``'s package, with ``probe`` installed
    (None: as it is)."""
    import json

    code = ("import sys, region_engine\n"
            + ("import region_schedule_probe\nregion_schedule_probe.install()\n" if probe else "")
            + f"region_engine.worker({repeats})\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(root), str(HERE / "benchmarks")]),
           "OPENBLAS_NUM_THREADS": "1", PROBE: probe or ""}
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, cwd=root)
    if done.returncode:
        raise RuntimeError(f"{root} {probe}: the worker failed\n{done.stderr[-3000:]}")
    data = json.loads(done.stdout.strip().splitlines()[-1])
    if not data.pop("module").startswith(str(root)):
        raise RuntimeError(f"{root}: imported another package")
    return data


def engine(baseline: Path, probe: str, rounds: int, repeats: int) -> None:
    """region_engine.py's cases: the baseline checkout, this one, and this one with ``probe`` installed, in
    interleaved rounds (the order rotated each round); per case the median over the rounds of each version's best
    CPU of ``repeats``, the probe's ratio to the baseline and to this checkout, its answers' largest relative
    difference from the baseline's and whether every verdict (word) is the same."""
    import statistics

    engine_ = _engine()
    runs = [("baseline", baseline, None), ("this", HERE, None), ("probe", HERE, probe)]
    cpu: dict[str, dict[str, list]] = {label: {} for label, *_ in runs}
    answers: dict[str, dict] = {}
    for k in range(rounds):
        for label, root, installed in runs[k % 3:] + runs[:k % 3]:
            for name, (best, numbers, words) in _engine_worker(root, installed, repeats).items():
                cpu[label].setdefault(name, []).append(best)
                answers.setdefault(label, {})[name] = (numbers, words)
    print(f"region_engine cases, median of {rounds} rounds (best of {repeats} each), CPU s, one BLAS thread, "
          f"OPENBLAS_CORETYPE={os.environ.get('OPENBLAS_CORETYPE', '(unset)')}")
    print("| case | baseline | this | probe | probe / baseline | probe / this | max rel diff (probe vs baseline) "
          "| verdicts |")
    print("|---|---|---|---|---|---|---|---|")
    for name in cpu["baseline"]:
        b, t, q = (statistics.median(cpu[label][name]) for label in ("baseline", "this", "probe"))
        (nb, wb), (nq, wq) = answers["baseline"][name], answers["probe"][name]
        same = "same" if wb == wq else "DIFFER"
        print(f"| {name} | {b:.4f} | {t:.4f} | {q:.4f} | {q / b:.3f} | {q / t:.3f} | {engine_._rel(nb, nq):.1e} "
              f"| {same} |")


def main() -> None:
    import argparse

    parser = argparse.ArgumentParser()
    parser.add_argument("--probe", choices=("bernoulli", "chain", "one"), default="bernoulli")
    parser.add_argument("--engine", action="store_true",
                        help="region_engine.py's cases: baseline, this checkout, this checkout probed")
    parser.add_argument("--baseline", default="/work/wt/base-region")
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    os.environ[PROBE] = args.probe
    if args.engine:
        engine(Path(args.baseline).resolve(), args.probe, args.rounds, 2)
        return
    reference = _bernoulli_reference()
    t0 = time.process_time()
    chain = _chain_cases()
    t1 = time.process_time()
    install()
    probe = _chain_cases()
    t2 = time.process_time()
    print(f"probe {args.probe!r}, OPENBLAS_CORETYPE={os.environ.get('OPENBLAS_CORETYPE', '(unset)')}")
    print(f"chain cases: chain iteration {t1 - t0:.3f} s CPU, probed {t2 - t1:.3f} s ({(t2 - t1) / (t1 - t0):.2f}x)")
    print("| case | verdicts | max rel diff |")
    print("|---|---|---|")
    for (name, words, numbers), (_, words_, numbers_) in zip(chain, probe, strict=True):
        pairs = [(x, y) for x, y in zip(numbers, numbers_, strict=False) if x == x and y == y and x != y]
        rel = max((abs(x - y) / max(abs(x), abs(y)) for x, y in pairs), default=0.0)
        changed = sum(a != b for a, b in zip(words, words_, strict=False)) + abs(len(words) - len(words_))
        verdicts = "same" if not changed else f"{changed} of {len(words)} differ"
        if changed and len(words) == 1:
            verdicts += f": {words_[0]}"
        print(f"| {name} | {verdicts} | {rel:.1e} |")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(HERE / "benchmarks"), str(HERE)])}
    done = subprocess.run([sys.executable, "-m", "pytest", "-n0", "-q", "-p", "region_schedule_probe",
                           "tests/closedloop/test_markov_region.py", "tests/closedloop/test_chain_certificates.py"],
                          capture_output=True, text=True, cwd=HERE, env=env)
    lines = done.stdout.strip().splitlines()
    failed = sorted({line.split("::")[1].split("[")[0] for line in lines if line.startswith("FAILED")})
    print(f"chain tests with the probe installed: {lines[-1] if lines else done.stderr[-500:]}")
    for name in failed:
        print(f"    failed: {name}")
    if args.probe in ("chain", "one"):
        _one_mode(reference)


if __name__ == "__main__":
    main()
