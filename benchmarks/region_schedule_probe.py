"""Probes, not capabilities: two schedules for one stabilisable-set iteration over M-mode chains, each put in place
of the chain iteration (chain_radius) to measure what it gains and loses, on chains and at one mode.

- ``bernoulli``: the Bernoulli iteration's schedule (region.homogeneous_riccati: shifted power steps of the
  least-squares Riccati step, handed to an unregularised Kronecker policy iteration after 30 steps, or after 4 where
  they shrink too slowly; balanced where P is graded, kept where its gain's radius is nearer) written for M modes,
  in place of chain_radius's reachable-part eigenpair behind the same controllability split.
- ``chain``: the chain iteration itself with two schedule changes: its first policy iteration at power step 4
  instead of 30, and an unbalanced pass whose P is graded (riccati_map.grading_scale) stopped at the checkpoint, the
  balanced pass redoing it (where the bracket of a graded P cannot close).

    OPENBLAS_NUM_THREADS=1 PYTHONPATH=$PWD python benchmarks/region_schedule_probe.py [--probe bernoulli|chain]

Prints the CPU of the chain cases of benchmarks/region_engine.py (chain memberships under both conventions, the
two_actuator rate map, a critical mean rate) unpatched and probed, their answers' largest relative difference and
the verdicts that change; the chain tests (tests/closedloop/test_markov_region.py, test_chain_certificates.py) run
with the probe installed (``pytest -p region_schedule_probe``); and for ``chain`` the one-mode cases of
region_engine.py against the Bernoulli iteration (CPU ratio, least radii apart, error from the hand value).
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


def _policy(P, A, B, channel, T, h, delivery):
    """Region's policy iteration on the coupled operator (unregularised): (P found, whether it moved)."""
    from packetloss_cvx.closedloop.mjls import second_moment_operator
    from packetloss_cvx.closedloop.riccati_map import POLICY_STEPS
    from packetloss_cvx.tolerances import CERTIFICATE_RTOL, RICCATI_RTOL

    M, n = P.shape[0], A.shape[0]
    best, last, moved = P.copy(), np.inf, False
    for _ in range(POLICY_STEPS):
        K, _ = _step(P, A, B, T, h, delivery)
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


#: the environment variable naming the probe `install` puts in place (read by the pytest plugin too)
PROBE = "REGION_SCHEDULE_PROBE"


def install() -> None:
    """Put the probe named by the environment's REGION_SCHEDULE_PROBE (default "bernoulli") in place."""
    from packetloss_cvx.closedloop import chain_radius
    from packetloss_cvx.closedloop.riccati_map import GRADED, grading_scale
    from packetloss_cvx.tolerances import HOMOGENEOUS_RICCATI_MAX_ITER

    if os.environ.get(PROBE, "bernoulli") == "bernoulli":
        chain_radius._balanced_eigenpair = balanced_eigenpair
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
    for seed in range(6):
        rng = np.random.default_rng(seed)
        n, m = int(rng.integers(1, 4)), int(rng.integers(1, 3))
        A, B = rng.normal(size=(n, n)), rng.normal(size=(n, m))
        ch = GilbertElliott(p=rng.uniform(0.05, 0.6, m), r=rng.uniform(0.05, 0.9, m))
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


def main() -> None:
    import argparse

    parser = argparse.ArgumentParser()
    parser.add_argument("--probe", choices=("bernoulli", "chain"), default="bernoulli")
    args = parser.parse_args()
    os.environ[PROBE] = args.probe
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
    if args.probe == "chain":
        _one_mode(reference)


if __name__ == "__main__":
    main()
