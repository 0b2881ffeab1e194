"""Independent references shared by several test files (written without the package's algebra)."""

import itertools
from fractions import Fraction

import numpy as np


def enumerated_operator(A, B, K, mu):
    """E[(A - B V K) ⊗ (A - B V K)] over all 2^m delivery patterns: independent of the closed form."""
    out = np.zeros((A.shape[0] ** 2,) * 2)
    for v in itertools.product((0, 1), repeat=len(mu)):
        p = np.prod([m if bit else 1 - m for bit, m in zip(v, mu, strict=True)])
        F = A - B @ np.diag(v) @ K
        out += p * np.kron(F, F)
    return out


def enumerated_radius(A, B, K, mu):
    """The mean-square radius of u = -K x by enumeration: rho of :func:`enumerated_operator`."""
    return float(np.max(np.abs(np.linalg.eigvals(enumerated_operator(A, B, K, mu)))))


def loss_pattern_probabilities(T, d, pi0, horizon):
    """P(v_0..v_{N-1} = pattern) of one hidden-Markov delivery channel, for every one of the 2^N patterns:
    pi0 D_{v_0} T D_{v_1} ... T D_{v_{N-1}} 1 with D_v = diag(d^v (1 - d)^(1 - v)) (the forward algorithm)."""
    T, d = np.asarray(T, float), np.asarray(d, float)
    out = {}
    for pattern in itertools.product((0, 1), repeat=horizon):
        row = np.asarray(pi0, float).copy()
        for t, v in enumerate(pattern):
            if t:
                row = row @ T
            row = row * (d if v else 1.0 - d)
        out[pattern] = float(row.sum())
    return out


def enumerated_chain_cost(A, B, state_weights, input_weights, initial_weight, x0, chains, U):
    """E[x0'Q x0 + sum_t (V_t u_t)'Psi_t (V_t u_t) + x_{t+1}'Omega_{t+1} x_{t+1}] without noise, as the sum over
    every joint loss pattern of the m independent chains ``(T, d, pi0)`` of its probability times the realised
    cost of the plan ``U`` (N×m) rolled through the plant: 2^(N m) roll-outs (all patterns rolled out together,
    one row each), none of the package's algebra."""
    N, m = U.shape
    per_channel = [loss_pattern_probabilities(T, d, pi0, N) for T, d, pi0 in chains]
    patterns = [np.array(list(p), dtype=float).reshape(-1, N) for p in per_channel]        # (2^N, N) per channel
    probs = [np.array(list(p.values())) for p in per_channel]
    joint = np.indices([len(p) for p in probs]).reshape(m, -1)        # the joint patterns, in itertools.product order
    prob = np.prod([probs[i][joint[i]] for i in range(m)], axis=0)
    keep = prob != 0.0
    v = np.stack([patterns[i][joint[i][keep]] for i in range(m)], axis=-1)          # (patterns, N, m)
    x = np.tile(np.asarray(x0, float), (v.shape[0], 1))
    cost = np.zeros(v.shape[0])
    for t in range(N):
        applied = v[:, t] * U[t]
        cost += np.einsum("pi,ij,pj->p", applied, np.diag(input_weights[t]), applied)
        x = x @ A.T + applied @ B.T
        cost += np.einsum("pi,ij,pj->p", x, state_weights[t], x)
    return float(x0 @ initial_weight @ x0) + float(prob[keep] @ cost)


def textbook_filter_path(A, Q, C, R, groups, P0, arrivals):
    """The Kalman filter's covariances along one arrival path, written as in a textbook (the rows of the groups
    that arrived, an explicit inverse): the predicted P^-_0..P^-_N and the filtered P_0..P_{N-1}."""
    Pm, predicted, filtered = P0.copy(), [P0.copy()], []
    for a in arrivals:
        rows = [r for j, g in enumerate(groups) if a[j] for r in g]
        if rows:
            Cr, Rr = C[rows], R[np.ix_(rows, rows)]
            K = Pm @ Cr.T @ np.linalg.inv(Cr @ Pm @ Cr.T + Rr)
            P = (np.eye(len(A)) - K @ Cr) @ Pm
        else:
            P = Pm
        filtered.append(P)
        Pm = A @ P @ A.T + Q
        predicted.append(Pm)
    return predicted, filtered


def exact_mean_states(A, B, x0, mu, U):
    """The mean states x_1..x_N of ``x_{t+1} = A x_t + B (mu_t u_t)`` from the floats A, B, x0, mu (N×m), U (N×m), in
    exact rational arithmetic (lists of Fractions): what a float rollout approximates."""
    n, m = np.shape(B)
    Af = [[Fraction(float(v)) for v in row] for row in np.asarray(A)]
    Bf = [[Fraction(float(v)) for v in row] for row in np.asarray(B)]
    x, out = [Fraction(float(v)) for v in x0], []
    for t in range(np.shape(U)[0]):
        z = [Fraction(float(mu[t][k])) * Fraction(float(U[t][k])) for k in range(m)]
        x = [sum(Af[i][j] * x[j] for j in range(n)) + sum(Bf[i][k] * z[k] for k in range(m)) for i in range(n)]
        out.append(x)
    return out


def exact_quadratic(states, Q):
    """sum_t x_t' Q_t x_t in exact arithmetic: states (lists of Fractions or floats), Q (n, n) or (N, n, n) floats."""
    Q = np.asarray(Q)
    total = Fraction(0)
    for t, x in enumerate(states):
        W = Q if Q.ndim == 2 else Q[t]
        x = [Fraction(v) for v in x]
        total += sum(x[i] * Fraction(float(W[i, j])) * x[j] for i in range(len(x)) for j in range(len(x))
                     if W[i, j] != 0)
    return total


def exact_plan_cost(system, U, input_weights, noise=0.0):
    """The expected cost of the float plan U (N×m) in exact arithmetic: x0'Q x0 + noise + sum_t mu_t w_t u_t^2 +
    x_{t+1}'Omega_{t+1} x_{t+1} with the exact mean states, the stage input weights ``input_weights`` (N×m: psi for
    the TCP-like cost, psi + (1 - mu) diag(Omega_g) for the UDP-like one) and the noise term taken as given."""
    mu = system.mu_schedule
    cost = exact_quadratic([system.x0], system.initial_weight) + Fraction(float(noise))
    for t in range(system.horizon):
        cost += sum(Fraction(float(mu[t, k])) * Fraction(float(input_weights[t, k])) * Fraction(float(U[t, k])) ** 2
                    for k in range(system.m))
    return cost + exact_quadratic(exact_mean_states(system.A, system.B, system.x0, mu, U), system.state_weights)


# ---------------------------------------------------------------- systems shared by several test files


def readme_system(N: int):
    """The README's example plant over N steps."""
    import packetloss_cvx as pl

    return pl.System(A=[[1.1, 0.2], [0, 0.9]], B=[[1], [0.5]], state_weight=[1, 1], input_weight=[0.5],
                     mu=[0.8], x0=[1, 0], horizon=N)


def unstable_system(rho: float, N: int):
    """A seeded random 2-state, 2-input plant of spectral radius rho over N steps (no noise, constant data)."""
    from packetloss_cvx.model.random_systems import random_system

    return random_system(np.random.default_rng(0), n=2, m=2, horizon=N, spectral_radius=rho, full_weights=False,
                         time_varying=False, non_stationary=False, noise=False, edge_mu=False)


def weighted_two_actuator(w: float):
    """The two_actuator example with its first state weight set to w (the weights then span w : 1)."""
    import packetloss_cvx as pl
    from packetloss_cvx.model.files import system_from_dict

    data = pl.load_example("two_actuator").to_dict()
    data["cost"]["state_weight"] = [w, 1.0]
    return system_from_dict(data)
