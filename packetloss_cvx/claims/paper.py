"""What the paper states and prints, in one place: each claim's statement and the numbers
the audit tries to reproduce (Tables I–II, the pendulum's maximiser, the allocation study).

Nothing here is computed: a value is the paper's, copied as printed.
"""

from __future__ import annotations

__all__ = [
    "ALLOCATION_ALPHA",
    "ALLOCATION_BETAS",
    "PENDULUM_NU_D",
    "STATEMENTS",
    "TABLE_1",
    "TABLE_1_MU",
    "TABLE_2",
    "TABLE_2_MU",
]

#: Table I: closed-loop eigenvalues of the pendulum (§V-A) at a shared channel nu = TABLE_1_MU.
TABLE_1 = {"tcp": [0.9497 + 0.0056j, 0.9497 - 0.0056j, -0.1148, 0.9978],
           "udp": [0.9907 + 0.0201j, 0.9907 - 0.0201j, 0.9729, 0.9382]}
TABLE_1_MU = (0.9,)

#: Table II: closed-loop eigenvalues of the two-actuator system (§V-B) at M = diag(TABLE_2_MU).
TABLE_2 = {"tcp": [-0.1082, -0.8938], "udp": [0.4904 + 0.0312j, 0.4904 - 0.0312j]}
TABLE_2_MU = (0.9, 0.5)

#: §V-A: the pendulum's cost difference J_Delta peaks at nu^D* = 0.0031.
PENDULUM_NU_D = 0.0031

#: §VI: for alpha >= 4.78 the cheapest UDP-like allocation of the two-actuator system has a
#: perfect channel, for each of these prices beta.
ALLOCATION_ALPHA = 4.78
ALLOCATION_BETAS = ((1.0, 1.0), (0.05, 1.0), (1.0, 0.05))

#: Each claim's statement, by claim id (the order is the audit's).
STATEMENTS: dict[str, str] = {
    "theorem-1-laws": "The optimal laws are U* = -G^-1 Omega_gp x (eq:opt-law-1, eq:opt-law-2).",
    "theorem-1-costs": ("The optimal costs are C - x'Omega_gp' G^-1 Vbar Omega_gp x (eq:TCP-opt-cost, "
                        "eq:UDP-opt-cost)."),
    "lemma-1": ("E[E'Omega E | I_k] = tr(Omega_l Sigma_W) (TCP-like) and U'Vbar Omega_d (I - Vbar) U + "
                "tr(Omega_l Sigma_W) (UDP-like)."),
    "lemma-quad-expectation": ("E[U'Upsilon Omega_g Upsilon U] = U'Vbar Omega_g Vbar U + U'Vbar Omega_d "
                               "(I - Vbar) U."),
    "expected-cost-tcp": ("The TCP-like expected cost (eq:lqg-sub-err with eq:TCP-prediction-error) equals "
                          "E[cost | F_k] of a fixed plan under the stated model."),
    "theorem-2": "For 0 < M < I, J*_udp - J*_tcp > 0.",
    "corollary-1": "||U*_udp||_2 < ||U*_tcp||_2.",
    "theorem-3": "If M2 > M1 then J*(M1) > J*(M2), for both protocols (and non-stationary channels).",
    "corollary-2": "At equal optimal cost the TCP-like protocol needs a smaller delivery probability.",
    "lemma-2": "dJ_Delta/dnu is given by eq:cost-diff-deriv.",
    "lemma-3": ("det f(nu) = 0 has the 2Nm solutions 1/(1 +- sqrt(1 + lambda_i)), lambda_i the eigenvalues of "
                "T (Omega_g + Psi)^-1 Omega_d Psi^-1."),
    "theorem-4": ("The maximiser of J_Delta over [0, 1] is the best Lemma 3 candidate at which the largest "
                  "eigenvalue of f vanishes."),
    "table-1": "Table I: closed-loop eigenvalues of the pendulum at nu = 0.9.",
    "table-2": "Table II: closed-loop eigenvalues of the two-actuator system at M = diag(0.9, 0.5).",
    "pendulum-maximiser": "For the pendulum, J_Delta peaks at nu^D* = 0.0031.",
    "allocation-udp-perfect-channel": ("UDP-like, two-actuator system, beta in {(1,1), (0.05,1), (1,0.05)}: for "
                                       "alpha >= 4.78 the cheapest allocation has a perfect channel."),
    "protocol-ranking-closed-loop": "The TCP-like law costs less than the UDP-like law when run in closed loop.",
    "mpc-vs-dp": ("(Not the paper's; a baseline.) Neither receding-horizon law beats the dynamic-programming optimum "
                  "for these losses in closed loop; the note says how far each is from it."),
}
