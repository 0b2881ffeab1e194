"""Every numerical tolerance of the package, in one place, with what it promises.

Change a value here, not a literal at the call site; tests import these names so that
a tolerance and the check that relies on it move together.
"""

from __future__ import annotations

import os

import numpy as np

__all__ = [
    "ACCEPTED_STATUSES",
    "CHAIN_DP_RTOL",
    "CLARABEL_DEFAULT",
    "CLARABEL_LINEAR_SOLVER",
    "CLARABEL_TIGHT",
    "CONSTRAINED_ACTIVE_RTOL",
    "CONSTRAINED_AGREEMENT_RTOL",
    "CONSTRAINED_KKT_RTOL",
    "CONTROLLABILITY_RTOL",
    "CROSS_CHECK_COST_RTOL",
    "CROSS_CHECK_FLOOR",
    "CROSS_CHECK_INPUT_ATOL",
    "DELIVERY_FACTOR_RTOL",
    "DENSE_MAX_CONDITION",
    "DENSE_RESIDUAL_RTOL",
    "KERNEL_MARGIN_RTOL",
    "KERNEL_POINT_RTOL",
    "KERNEL_VALUE_RTOL",
    "KERNEL_ZERO_ATOL",
    "MEMORY_BUDGET_BYTES",
    "PLAN_COST_RTOL",
    "SELF_CHECK_ATOL",
    "SELF_CHECK_RTOL",
    "SOFT_WEIGHT_MAX_RATIO",
    "STATIONARY_RTOL",
    "PATH_AGREEMENT_RTOL",
    "PSD_FACTOR_RTOL",
    "PSD_RTOL",
    "ROW_SUM_ATOL",
    "STATIONARY_GAP",
    "SYMMETRY_RTOL",
]

#: A weight is symmetric when ||W - W'|| <= SYMMETRY_RTOL * ||W|| (spectral norms) ...
SYMMETRY_RTOL = 1e-10
#: ... and positive semidefinite when its least eigenvalue is >= -PSD_RTOL * ||W|| (rounding of a
#: computed F F' is about n eps ||W||); such rounding-level negatives are set to zero. With the
#: former max(1, ||W||) * 1e-10, the eigenvalue -99 beside 1e12 passed and costs went negative.
PSD_RTOL = 1e-12

#: psd_factor drops eigen-directions below PSD_FACTOR_RTOL * (largest eigenvalue): purely relative,
#: so a weight of 1e-15 is kept (with max(1, .) the QP once dropped every state weight below 1e-14).
PSD_FACTOR_RTOL = 1e-14

#: model.chain.delivery_factor keeps the innovations factor F of a channel's delivery covariance C only where
#: max|F F' - C| <= DELIVERY_FACTOR_RTOL * max mu_t (the second moments' scale: C's own diagonal mu (1 - mu) is off by
#: about eps mu). Measured: 4.6e-17 (pendulum_bursty, N = 20), at most 4.0e-15 over 200 random Gilbert and three-state
#: chains with N <= 60 (beliefs at the simplex's corners, deliveries certain or impossible, included) and 1.0e-15 for
#: channels delivering with probability 0.9999 and 0.999999 in their bad state (relative to max C_tt these read 1.4e-11
#: and 1.4e-9: C's rounding, not F's); 1e-12 leaves two and a half decades.
DELIVERY_FACTOR_RTOL = 1e-12

#: Clarabel's linear solver, pinned in both settings below (so wherever the package builds Clarabel's settings: cvxpy's
#: ``problem.solve``, the compiled ClarabelProgram, the allocation LPs): QDLDL, Clarabel's simplicial LDL. Its default
#: "auto" (0.11) switches to faer's supernodal LDL (on all cores) where it judges the KKT system's fill large. On the
#: constrained loop's program with one chance row (N second-order cones of size up to N + 2) it does so at N = 135
#: (n = 4, m = 2; not at 120), and at N = 200 the solve, the same nine interior-point iterations, took 18 and 7.9 times
#: QDLDL's (1685 against 92 ms at n = 2, m = 1; 1795 against 228 ms at n = 4, m = 2; benchmarks/mpc_solve_time.py,
#: one BLAS thread, CPU time); where it picked faer without that (N = 170, n = 2, m = 1; N = 200, m = 1) QDLDL took
#: 1.04 to 1.13 times as long. Where "auto" picks QDLDL the floats are the same: in tests/qp, tests/montecarlo,
#: tests/sensing, tests/allocation, tests/claims, the constraint CLI tests and the tutorials it picked faer for two
#: programs only (the dense 64 x 64 condensed QP; the Markov UDP QP of pendulum_bursty, whose cost moved by 1.5e-16
#: relative and its cross-check's input difference from 2.866e-12 to 2.877e-12).
CLARABEL_LINEAR_SOLVER = "qdldl"

#: Clarabel for the expected-cost QP twin: tight enough that the cross-check below is meaningful.
CLARABEL_TIGHT = {"tol_gap_abs": 1e-10, "tol_gap_rel": 1e-10, "tol_feas": 1e-10, "max_iter": 400,
                  "direct_solve_method": CLARABEL_LINEAR_SOLVER}

#: Clarabel's own defaults (1e-8 gap and feasibility), tried where the tight settings stall. Spelled
#: out: cvxpy re-solves a problem by updating the cached solver's previous settings with the ones
#: passed, so an empty dict after CLARABEL_TIGHT would run the tight settings again.
CLARABEL_DEFAULT = {"tol_gap_abs": 1e-8, "tol_gap_rel": 1e-8, "tol_feas": 1e-8, "max_iter": 200,
                    "direct_solve_method": CLARABEL_LINEAR_SOLVER}

#: The largest soft-row weight rho the constrained QP is solved with, relative to its cost scale (the largest
#: weight, ConstrainedQP.scale): the program carries rho / scale per unit of slack, and beyond the solver's range it
#: comes back "solver_error" or a false "infeasible". Measured (Clarabel, Haswell kernel; 40 random systems, n <= 3,
#: m <= 2, N = 6, weights 1e-3..1e3, x0 1e-2..1e2, soft x_max at 0.3 |x0|, both protocols): every solve optimal up to
#: 1e4; at 1e8 39 of 40 (the 40th refused by its KKT residual from 1e6 on, weight-sensitive, not the range); at 1e9
#: 35-37 (the rest "infeasible" undecided); at 3e9 26-29 (10 solver errors); two_actuator --x-max 0.5 optimal to
#: 1e10, "solver_error" at 1e12, a false "infeasible" from 1e14. A weight of 1e8 times the cost scale already holds
#: a soft row as hard as the solver can (an exact penalty: any rho above the row's multiplier).
SOFT_WEIGHT_MAX_RATIO = 1e8

#: The constrained expected-cost QP (qp/constrained.py). A solve is refused when the KKT residual of its answer
#: (stationarity, primal and dual feasibility, complementarity, each relative: ConstrainedQP.kkt), evaluated on the
#: plan's moments by their own forward recursion, exceeds CONSTRAINED_KKT_RTOL. Measured (142 solves: n = 2, m = 2,
#: N = 4, 20 seeds, both protocols and formulations, input/rate/chance rows binding; Haswell kernel): the polished
#: answers <= 5.9e-16; Clarabel's own answers up to 7.8e-6 (median 2.3e-8: chance rows stall the tight 1e-10
#: settings, and the default 1e-8 answer is taken), and a raw residual of 1.1e-7 went with U off by 2.8e-4 (the square
#: root of the gap): 1e-9 refuses an answer the polish could not make exact rather than pass it. On 240 random
#: systems (n, m <= 4, N <= 11, input/rate/state/chance rows, a third soft): 153 optimal (KKT <= 7.3e-11, the one
#: unpolished answer at a chance row's kink), 87 proven infeasible (each soft twin reports a violation), none refused.
#: Each residual is relative to its own terms' size, floored at CROSS_CHECK_FLOOR of the problem's data
#: (ConstrainedQP.data_scale: the cost weight size^2, the slope weight size, size the largest of max|x0|, the noise's
#: spread and the finite bounds): near x0 = 0 every term is rounding of zero, and the unfloored ratios were O(1)
#: (two_actuator, x_max = 2, x0 = 0 or 1e-100: "1.49 (stationarity)", the plan U = 0 refused).
CONSTRAINED_KKT_RTOL = 1e-9
#: A constraint is reported binding when g(U) >= -CONSTRAINED_ACTIVE_RTOL max(1, |b|) (Clarabel's tight feasibility
#: tolerance 1e-10 with a margin), and a soft row violated when its slack exceeds the same.
CONSTRAINED_ACTIVE_RTOL = 1e-7
#: Two formulations (condensed, sparse) or two solvers (Clarabel, scipy's SLSQP on the same expected cost; OSQP at
#: eps 1e-9) agree on a constrained plan to this, relative to max|U| (and on its cost relative to J). Measured on the
#: 142 solves above: condensed vs sparse <= 2.2e-15, Clarabel vs SLSQP (three restarts at ftol 1e-14) <= 3.0e-7
#: (median 8.9e-9; SLSQP's own accuracy: its first run alone was 1.8e-6 off).
CONSTRAINED_AGREEMENT_RTOL = 1e-6

#: The only solver status taken as an answer. ``optimal_inaccurate`` is never accepted: a caller
#: may retry with other settings, and otherwise raises SolverError with the status.
ACCEPTED_STATUSES = frozenset({"optimal"})

#: The QP twin agrees with the closed form when the mean applied inputs agree,
#: max |Vbar (U_qp - U*)| <= CROSS_CHECK_INPUT_ATOL * max |Vbar U*| ...
CROSS_CHECK_INPUT_ATOL = 1e-6
#: ... and |J_qp - J*| <= CROSS_CHECK_COST_RTOL * |J*| (relative at every scale: the QP is solved
#: with its weights and x0 scaled to one, so its accuracy is relative too).
CROSS_CHECK_COST_RTOL = 1e-7
#: Below CROSS_CHECK_FLOOR times the problem's own scale (largest weight times max|x0|^2 for costs,
#: max|x0| for inputs) a difference is rounding: against an exact zero (no state weight) the QP
#: returns 7e-33 with weights and x0 of one.
CROSS_CHECK_FLOOR = 1e-9

#: A dense solve G U = b is kept only if ||G U - b|| <= DENSE_RESIDUAL_RTOL * ||G|| ||U|| + ||b|| scaled
#: likewise; past it the dense path has lost the answer and raises NumericalError.
DENSE_RESIDUAL_RTOL = 1e-9

#: The dense path of Theorem 1 is refused when the condition estimate
#: (trace Omega_g + max Psi) / min Psi exceeds this. Measured: its relative error is about
#: estimate * 2.2e-16 / 25 (pendulum at mu = 1: N = 200 gives 3.4e11 and a gain off by 3e-6;
#: a rho = 1.2, N = 60 plant gives 9.5e10 and 8e-7), so 1e8 keeps it near 1e-9.
DENSE_MAX_CONDITION = 1e8

#: A closed-form cost is kept only if it agrees with the forward pass of its own plan (a sum of
#: nonnegative terms, free of cancellation): |J_closed - J_forward| <= SELF_CHECK_RTOL * J_forward
#: + SELF_CHECK_ATOL * ||P_0|| ||x||^2 (the last term only for the recursion, whose x'P_0 x has
#: that rounding scale). Well-posed systems agree to 1e-14 (300 random ones: worst 4.7e-15);
#: badly scaled weights (1e10 against 1) disagree by 5e-7 and more. closed_form then reports J_forward
#: (FORWARD_COST_ROUNDING), the more accurate of the two.
SELF_CHECK_RTOL = 1e-9
SELF_CHECK_ATOL = 1e-13

__all__ += ["FORWARD_COST_ROUNDING"]

#: closed_form reports the forward cost of its own plan, not the x'P_0 x (or C - g'Vbar G^-1 g) it checks against
#: it: that one cancels, off by up to about eps ||P_0|| ||x||^2; the forward sum's terms are nonnegative and its
#: states cancel only to about eps sqrt(||Q|| ||x||^2 J*), and the plan's own rounding enters it at second order.
#: |J_reported - J*| <= FORWARD_COST_ROUNDING eps sqrt(||Q|| ||x||^2 J*) (N = 1, ||x|| the larger of |x0|, |A x0|).
#: Measured against the exact rational J* of 238 random one-step plants (n = 1..3, one input, the first state's
#: weight scaled by 1 to 1e14; tests/lq/test_costs.py), under OpenBLAS's Haswell and Prescott kernels: the forward
#: cost within 1.2 of that bound's unit, x'P_0 x up to 1700 times it (1.2e-9 relative where J* = 246 and
#: ||Q|| ||x||^2 = 3.4e9: the property test's failure of 1.35e-9 against its 1e-9).
FORWARD_COST_ROUNDING = 4.0

#: The backward passes (the Riccati recursion, the Lyapunov sums) close a stationary tail (A, B, the
#: weights and mu the same at every earlier step) once their estimated remaining drift is below
#: STATIONARY_RTOL relative: last change * q / (1 - q) <= STATIONARY_RTOL * max|P|, with q the
#: asymptotic contraction per step (rho(A - B M K)^2 for the Riccati map, rho(A)^2 for the Lyapunov sum;
#: never closed when q >= 1). The iterates then jitter at rounding level (measured 7e-17 to 4e-16 on the
#: N = 10^4, n = 4, m = 2 benchmark, contraction 0.29), so closing leaves the costs where the full pass puts
#: them: against the full pass, worst 4.6e-14 relative (costs) and 9.6e-15 (plans, gains) over
#: benchmarks/kernel_agreement.py's 28 long horizons (N = 200 to 10^4, rho(A) 0.5 to 1.05); benchmarks/run.py
#: section 18: 1.7e-16 to 3.3e-16 at N = 10^3 to 10^5.
STATIONARY_RTOL = 1e-14
#: Two exact paths to the same numbers (the backward pass by doubling and step by step; a rollout by powers and
#: scans and step by step) agree to PATH_AGREEMENT_RTOL of each array's largest entry: every cost, plan and gain.
#: Measured: worst 8.6e-14 over benchmarks/kernel_agreement.py's 405 systems, doubling against the step-by-step pass
#: (closed_form of the slowly converging plant with one usable input, N = 10^4; its gains 6.5e-14; at N = 2000 the
#: doubled pass is within 2.7e-14 of an 80-bit pass, the step-by-step one within 8.3e-14).
#: The exact Markov cost's forward pass in blocks with its Stein-summed tail against the plain step-by-step loop:
#: worst 1.9e-13 (benchmarks/markov_tail.py, a noisy plan over N = 8000; each within 1.0e-13 of an 80-bit loop).
PATH_AGREEMENT_RTOL = 1e-12

#: The TCP-like DP behind a chain (closedloop.chain_dp) and its independent references agree within CHAIN_DP_RTOL
#: relative: the brute-force DP over delivery histories (probabilities as sums over hidden paths), the enumerated cost
#: of its own law, the mode engine's forward cost where the acknowledgements reveal the state, the Bernoulli DP of a
#: memoryless chain, the Bernoulli step as a mixture of 2^m delivery vectors (tests/closedloop/test_chain_dp.py).
#: Measured: at most 5.0e-16 against the brute force (20 systems, five chains, n = 2, N = 3 to 4; 3.4e-16 under
#: Prescott), 5.7e-16 against the Bernoulli DP (10 memoryless chains, N = 12), 0 against the mode engine on
#: pendulum_bursty, 4.9e-16 of the largest entry for the mixture step (20 random steps, n = 3, m = 2).
CHAIN_DP_RTOL = 1e-12
#: One Markov chain written two ways, equal to rounding (GilbertElliott(p=[0.02], r=[0.18]) and the transition
#: matrix a person types, [[0.98, 0.02], [0.18, 0.82]]: 1 - r is 0.8200000000000001 in binary), gives numbers that
#: agree within CHAIN_FORM_RTOL relative (KERNEL_ZERO_ATOL absolute beside quantities that are zero in exact
#: arithmetic). Measured on pendulum_bursty's solve and simulate --closed-loop JSON: worst 1.2e-12, the dense UDP
#: plan's inputs, whose own accuracy is about that (the recursion and the dense route disagree there by 7.6e-13 to
#: 1.25e-12); the coupled Riccati gains, mode start and jump-law costs of two two-state channels: 5e-17 of their
#: largest entries.
CHAIN_FORM_RTOL = 1e-10
#: A Markov channel's transition row, belief or state distribution (model/channel.py) is accepted when it sums to
#: 1 within ROW_SUM_ATOL, then divided by its sum: decimal entries such as 0.7, 0.2, 0.1 sum to 1 - 1.1e-16
#: in binary, and a file's rows are rarely written to more than 9 digits; a row off by more is a typing error.
ROW_SUM_ATOL = 1e-9
#: A chain's stationary distribution is unique (eigenvalue 1 simple) when the smallest singular value of
#: [T' - I; 1'] exceeds STATIONARY_GAP. Two states: that value is p + r (measured: 2.0e-3, 2.0e-6, 2.0e-9, 2.0e-12
#: at p = r = 1e-3 ... 1e-12), so the Gilbert–Elliott rule (p + r > 0) and this one differ only for p + r below
#: 1e-12, where the chain needs 10^12 steps to forget its start and a stationary start means nothing.
STATIONARY_GAP = 1e-12

#: controllability_split (linalg.py) counts a direction as reached by the inputs when its singular value in the
#: staircase exceeds CONTROLLABILITY_RTOL * ||[A, B]||_2. Measured (benchmarks/controllability.py): on 2,000 random
#: plants with a planted uncontrollable part rotated by a random orthogonal matrix (n <= 12), the largest coupling
#: the staircase drops is 1.5e-13 relative under the Haswell, Prescott, Nehalem, Sandybridge, Zen and SkylakeX
#: kernels (rounding of the rotation, amplified by the subspace's sensitivity), and generic random plants keep
#: singular values down to 2e-12 (single-input, n = 12: Krylov directions near dependent). No threshold separates
#: such plants for every input: the split reports ``dropped`` and ``kept`` so that a verdict resting on it can be
#: called exact (``dropped == 0``: a mode no input touches, exact block structure) or said to rest on a rank decision.
CONTROLLABILITY_RTOL = 1e-12

#: Two runs of one computation under different BLAS kernels (OPENBLAS_CORETYPE) round differently. A number a
#: user sees may move between kernels by no more than what it is trusted to: a closed-form cost, a table's
#: eigenvalue or a radius by KERNEL_VALUE_RTOL (= SELF_CHECK_RTOL, what the self-check guarantees; measured on
#: reproduce's results.json, Haswell against Prescott: 4.6e-13 worst, 7.0e-12 for an eigenvalue of A - BK) ...
KERNEL_VALUE_RTOL = SELF_CHECK_RTOL
#: ... with an absolute floor for quantities that are exactly zero in exact arithmetic (a mean-square radius at a
#: deadbeat point: 1e-32 to 1e-30 measured, i.e. (eps ||A||)^2), times the quantity's own scale (1 for a radius,
#: a claim's tolerance for its worst margin) ...
KERNEL_ZERO_ATOL = 1e-12
#: ... a maximiser's location by KERNEL_POINT_RTOL: at a smooth maximum the location is determined only to about
#: the square root of the value's relative accuracy (measured 4.3e-8 for the two-actuator maximiser, 1.3e-9 for
#: the pendulum's; the values agree to 7e-16) ...
KERNEL_POINT_RTOL = 1e-6
#: ... a holding claim's worst margin (its tolerance less the largest error, an error at rounding level) by
#: KERNEL_MARGIN_RTOL of the margin (measured: lemma-2's 9.989e-6 against 9.972e-6, 1.7e-3; cost-split-sensor
#: 1.2e-3; docs/claims.md's audit under seven kernels: cost-split-sensor 1.2e-3, lemma-2 8.3e-4, theorem-1-laws
#: 3.7e-7, mpc-vs-dp 6.7e-8, a failing claim's at most 1.3e-8), as only the verdict, not the rounding error's digits,
#: is a result ...
KERNEL_MARGIN_RTOL = 1e-2
#: ... and an allocation's communication cost and lower bound by its certified relative gap (each run's are within
#: the gap of the same optimum; measured 5.5e-5 at the default gap 1e-4). Its point mu is not unique to better than
#: the gap where the optimum is flat (measured: a component 1.2e-6 against 2.4e-7), so it is compared through its
#: cost, not entry by entry.

#: What one dense computation or one QP may allocate: a quarter of the machine's memory.
MEMORY_BUDGET_BYTES = 0.25 * (os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
                              if hasattr(os, "sysconf") else 8 * 2**30)

#: The expected cost of a given plan (expected_cost, recursion_cost without states, the Markov exact_cost) is
#: returned only where its a-posteriori error bound (recursion.plan_cost: the rolled-out states' residuals in
#: twice the precision, their propagation, the sum's rounding) is at most PLAN_COST_RTOL of it, as a closed
#: form's cost is trusted to SELF_CHECK_RTOL; beyond it NumericalError. The QP's objective is checked against
#: the forward cost of its plan where that cost is resolved so (elsewhere the cross-check binds).
#: Measured against the exact rational cost of the float plan (fractions): on 7,753 plans over test_properties.py's
#: random systems (3,753 closed-form plans, 4,000 random ones; rho(A) 0.3 to 3, N <= 40, a state weight up to 1e14)
#: the bound held on every one; 70 were refused (closed-form plans of rho = 3 plants, N 23-40, steering the state to
#: zero), each truly off by 1.26e-9 to 1 (relative; the bound within 1 % of the true error there), and every one
#: returned was truly within 9.9e-10 (Haswell kernels; under Prescott, 4,840 other plans: the bound held on all, 40
#: refused each truly off by 1.07e-9 or more, those returned within 8.9e-10). The pendulum (rho = 1.061) at
#: N = 400: bound 2.217e-13, true 2.206e-13 (returned); N = 500: 7.72783e-7 against 7.72782e-7 (refused);
#: N = 2000: 1.10977283659e78 against 1.10977283658e78 on an exact cost of 1.4687e80 (refused; the optimum is 25445).
#: A stable plant (n = 4, m = 2, N = 10^5, a random plan): 1.6e-15 relative.
PLAN_COST_RTOL = SELF_CHECK_RTOL

# ------------------------------------------------------------------ channel allocation (allocation/)

__all__ += [
    "ALLOCATION_AIM_RTOL",
    "ALLOCATION_COST_RTOL",
    "ALLOCATION_EDGE_ATOL",
    "ALLOCATION_EDGE_RTOL",
    "ALLOCATION_GAP_DEFAULT",
    "ALLOCATION_GAP_FLOOR",
    "ALLOCATION_GAP_MIN",
    "ALLOCATION_INCUMBENT_SHARE",
    "ALLOCATION_LP_FEASIBILITY",
    "ALLOCATION_MIN_BOX_WIDTH",
    "MIN_COST_RTOL",
]

#: The allocation's line searches (regula falsi, boxes.bracket) aim at alpha (1 - ALLOCATION_AIM_RTOL), not
#: at alpha: converging onto the crossing itself left an incumbent at J* = alpha - 1e-15, which another
#: evaluation path of J* (the reported cost, closed_form) put 6e-14 above alpha. Only the aim: every
#: decision still compares with alpha. (Where the two crossings lie more than the search's tol apart, the margin
#: cannot be kept within tol: boxes.bracket then ends just beyond alpha's crossing.)
ALLOCATION_AIM_RTOL = 1e-10

#: Every proof of the allocation that rests on a closed-form cost J*(mu) trusts it to this
#: relative accuracy (the recursion and the dense form agree to ~1e-12): a box is pruned as
#: infeasible only when J*(upper corner) > alpha (1 + ALLOCATION_COST_RTOL), and a tangent cut
#: of J*_tcp is loosened by ALLOCATION_COST_RTOL (|J*| + ||grad J*||_1).
ALLOCATION_COST_RTOL = 1e-9

#: The smallest relative optimality gap an allocation may be asked to certify (`gap`): below
#: it the gap would be finer than the closed form's trusted accuracy. The largest is < 1.
ALLOCATION_GAP_MIN = 1e-9
#: The gap certified unless asked otherwise.
ALLOCATION_GAP_DEFAULT = 1e-4
#: gap = (beta'mu - lower_bound) / max(beta'mu, ALLOCATION_GAP_FLOOR) (results.Allocation).
ALLOCATION_GAP_FLOOR = 1e-12

#: A lower corner of a box is raised by bisection along an edge to within
#: ALLOCATION_EDGE_ATOL + ALLOCATION_EDGE_RTOL * (edge length), on the infeasible side.
ALLOCATION_EDGE_ATOL = 1e-9
ALLOCATION_EDGE_RTOL = 1e-6

#: The bisection that moves an incumbent onto the cost boundary stops within this share of
#: the requested gap, so its slack costs at most that share of the certificate.
ALLOCATION_INCUMBENT_SHARE = 1e-3

#: Boxes narrower than this on their widest (weighted) side are not split further; their
#: bound stays in the reported lower bound.
ALLOCATION_MIN_BOX_WIDTH = 1e-12

#: HiGHS's primal and dual feasibility tolerance for the LPs over sub-boxes; a returned mu
#: satisfies every (unit-scaled) row of G mu <= h to this absolute tolerance.
ALLOCATION_LP_FEASIBILITY = 1e-9

#: min_cost certifies the least reachable J* to this relative gap (status "optimal").
MIN_COST_RTOL = 1e-6

__all__ += ["ALLOCATION_CLARABEL_ATTEMPTS"]

#: The allocation SOCPs (epigraph form, cost scaled by 1 / (alpha - C)) try the tight settings,
#: then Clarabel's defaults. On 200 test problems (a 3-channel case over 40 random
#: systems, the 2-channel test systems, random m = 2..4) the tight settings end "optimal" on
#: 175 and the defaults on all 200; the former single summed constraint on 164.
ALLOCATION_CLARABEL_ATTEMPTS = (CLARABEL_TIGHT, CLARABEL_DEFAULT)

__all__ += ["ALLOCATION_TCP_ATTEMPTS"]

#: The TCP-like allocation program (allocation.tcp.TCPProgram, which the UDP-like lower bounds solve too) tries
#: the tight settings without Clarabel's equilibration first, then the defaults (equilibrated, as above).
#: Without an equilibration to carry over, the first attempt runs on a solver kept and updated with each
#: call's data (convex.ClarabelProgram): the same floats as a new solver, 0.4 ms of set-up saved, and each
#: interior-point iteration about 10 % cheaper. Its answers are certified as before (closed form, tangent
#: cuts), so the settings decide speed only. Measured on 120 random programs (30 of benchmarks/run.py's
#: m = 3, N = 40 kind, 90 random m = 2..4, N = 5..40, half with a budget row): the first attempt ends
#: "optimal" on 89 (90 equilibrated), and where both do their mu differ by at most 1.2e-6; on the
#: benchmark's 18 calls (seeds 1-3) on all 18 (15 equilibrated: three second attempts), mu within 1.2e-10.
ALLOCATION_TCP_ATTEMPTS = ({**CLARABEL_TIGHT, "equilibrate_enable": False}, CLARABEL_DEFAULT)

__all__ += ["CONSTRAINED_ATTEMPTS"]

#: The constrained QP's compiled program (qp.constrained.ConstrainedQP, the default Clarabel path) tries the tight
#: settings and then the defaults without Clarabel's equilibration, on solvers kept and updated with each re-solve's
#: data (convex.ClarabelProgram: the same floats as a new solver, the set-up saved, an answer that depends on its
#: own data only), and last the defaults equilibrated, cold. Its answers are polished and KKT-checked as before, so
#: the settings decide speed only. Measured on 321 re-solves (60 random systems, n = 2..4, m = 1..3, N = 4..20, both
#: protocols, input, rate and chance rows binding, three x0 each): the first attempt ends "optimal" on 273, the
#: second on the other 48, none needs the third (problem.solve's equilibrated tight and default attempts: 272 and
#: 49); the returned plans agree with problem.solve's to 4.0e-15 relative to max|U|.
CONSTRAINED_ATTEMPTS = ({**CLARABEL_TIGHT, "equilibrate_enable": False},
                        {**CLARABEL_DEFAULT, "equilibrate_enable": False}, CLARABEL_DEFAULT)

__all__ += ["ALLOCATION_CUT_STEPS"]

#: The TCP-like lower bounds take tangent cuts of the convex J*_tcp at the solver's point and at
#: +- each of these steps along every axis: the cuts' maximum brackets the optimum on whichever
#: side the solver's point errs (by up to ~3e-5 at the default tolerances), leaving an error of
#: about curvature * step^2 instead of gradient * error. Measured on two_actuator, min J*_tcp
#: with mu1 + mu2 <= 1.2: one cut at the point certifies a relative gap of 1.2e-6, these 2.4e-9.
ALLOCATION_CUT_STEPS = (1e-3, 1e-4, 1e-5)

__all__ += ["BRUTE_FORCE_BISECTION_TOL", "BRUTE_FORCE_ROW_ATOL"]

#: The brute-force reference (allocation/brute_force.py) bisects mu2 to this width, keeping the
#: feasible end, so its answer is beta'mu at a feasible point within ~1e-10 of the boundary ...
BRUTE_FORCE_BISECTION_TOL = 1e-10
#: ... and treats a row without mu2 as violated only beyond this absolute slack.
BRUTE_FORCE_ROW_ATOL = 1e-12

# ------------------------------------------------------------------ closed loop (simulation/)

#: A loop is reported mean-square stable only when the spectral radius of its second-moment
#: operator is below 1 - MEAN_SQUARE_MARGIN: ARPACK and the Kronecker eigenvalues agree to about
#: 1e-12 (random n = 3..20 laws), so a radius within 1e-9 of one is not proved either way.
MEAN_SQUARE_MARGIN = 1e-9
#: ARPACK's relative accuracy for the radius of the second-moment operator (method="krylov").
ARPACK_TOL = 1e-12
#: method="auto" forms the n^2 x n^2 Kronecker matrix up to this n (O(n^6): 20 -> 400 x 400,
#: about 50 ms) and works on the operator beyond it.
KRONECKER_MAX_N = 20
#: The stationary second moment and the cost-to-go of a law are solved densely (n^2 x n^2 LU)
#: up to this n, by GMRES on the operator beyond it; either answer is kept only if its relative
#: residual ||X - L(X) - C|| / ||X|| is at most MOMENT_RESIDUAL_RTOL.
MOMENT_DENSE_MAX_N = 30
MOMENT_RESIDUAL_RTOL = 1e-9
#: The modified Riccati equation (simulation/riccati.py) has converged when
#: ||P_next - P|| <= RICCATI_RTOL ||P||; its value iteration gives up after RICCATI_MAX_ITER steps. Once ||P||
#: exceeds RICCATI_DIVERGENCE times the weights (and at each further factor RICCATI_DIVERGENCE^(1/4)) its direction
#: is checked in exact arithmetic as a certificate that no law stabilises ("no stabilising solution" only then):
#: growth is no proof, a chain of integrators (1.001 on the diagonal, mu = 0.0186) has an optimum with ||P|| = 2e16.
RICCATI_RTOL = 1e-12
RICCATI_MAX_ITER = 20000
RICCATI_DIVERGENCE = 1e14
#: Critical delivery probabilities along a ray are bisected to this width in t.
CRITICAL_MU_TOL = 1e-6
__all__ += ["RESOLVED_MIN"]

#: A nonzero quantity below RESOLVED_MIN = tiny / eps (2.2e-308 / 2.2e-16, about 1.0e-292) has rounding-level parts
#: in the subnormal range, where double precision keeps fewer than 53 bits: the sums and products that computed it
#: may have lost digits, and nothing bounds how many. A check meeting one (the audit's costs and plans of a system
#: whose weights or x0 are scaled towards 1e-300) reports the case undecided. A guarantee, not an observed edge:
#: measured on two_actuator with x0 scaled by c (costs 2.8 c^2), the closed form's cost against c^2 times the
#: unscaled one is off by 4.1e-15 at c = 1e-140 (2.8e-280), 6.3e-15 at 1e-150 (2.8e-300, already below the bound),
#: 9.8e-15 at 1e-155 (subnormal), and at 1e-160 (2.8e-320) its self-check fails, 1.8e-4 apart.
RESOLVED_MIN = float(np.finfo(float).tiny / np.finfo(float).eps)
__all__ += ["QP_PIN_MU"]

#: The QP twin carries the mean delivered input z = mu u with the weight (psi + ...) / mu, and pins z = 0
#: (the input is never delivered) where mu <= QP_PIN_MU. Measured on two_actuator, both protocols and
#: formulations: Clarabel agrees with the closed form to 4e-12 for mu_1 from 1e-3 down to 1e-30 and fails
#: at 1e-60. Pinning a channel of delivery probability mu changes J* by at most mu sum_t psi u_t^2 (the
#: envelope gradient), about 1e-30 times the weights' spread: far below CROSS_CHECK_COST_RTOL, which binds.
QP_PIN_MU = 1e-30
__all__ += ["QP_RESCALE_BELOW"]

#: The QP twin solves its problem scaled to a largest weight of one and max|x0| = 1. Clarabel stops at an
#: absolute duality gap of tol_gap_abs, or a relative one of tol_gap_rel max(1, |objective|): below an
#: objective of one both are absolute, 1e-10 (CLARABEL_TIGHT). Where the scaled minimum v is below
#: QP_RESCALE_BELOW = 1e-10 / CROSS_CHECK_COST_RTOL = 1e-3 that gap may exceed CROSS_CHECK_COST_RTOL v
#: (measured: v ~ 1e-11 with weights spanning 1e12 came back 0.5-6.5 % high, status 'optimal'); there the
#: QP is scaled again by its first value and re-solved (the minimiser does not change), so that v is O(1)
#: and the relative criterion governs. A value still below it after the passes raises NumericalError.
QP_RESCALE_BELOW = max(CLARABEL_TIGHT["tol_gap_abs"], CLARABEL_TIGHT["tol_gap_rel"]) / CROSS_CHECK_COST_RTOL
__all__ += ["CERTIFICATE_KERNEL_RTOL", "CERTIFICATE_RTOL", "HOMOGENEOUS_RICCATI_MAX_ITER"]

#: An infeasibility certificate P of the stabilisable set (simulation/region.py) is accepted when the bound it proves
#: on every law's mean-square radius, the largest c with R(P) >= c P (R the homogeneous Riccati map, computed as a
#: least-squares residual), is >= 1 - CERTIFICATE_RTOL: a band on the radius (not on the least
#: eigenvalue of T_mu(P) over ||A'PA|| + ||P|| + ||B'PB||, which shrinks like 1 / ||K||^2 with the gain and would pass a
#: P from 1e-6 inside S where the gains were about 600). Measured at the exact boundary with the homogeneous Riccati
#: eigenvector (scalar a = 2, decoupled (2, 1.5) and (3, 1.2, 0.5), one state with two channels): c - 1 from -6.7e-16
#: to +4.4e-16; 1e-9 inside S -1.4e-9 to -4e-9 (refused), as an inside certificate needs rho < 1 - 1e-9.
CERTIFICATE_RTOL = 1e-12
#: In that bound the directions P does not weigh (its eigenvalues at or below n eps max) are minimised out; one that
#: R's factor F maps to at most CERTIFICATE_KERNEL_RTOL ||F|| counts as no direction: rounding (a rank-one P whose
#: eigenvector is tilted by 5e-14 relative, random plant seed 2 of tests/closedloop/test_region.py, had left
#: c = 1.3e-8 where it is 3.26; the tilt is far below any direction a law could use).
CERTIFICATE_KERNEL_RTOL = 1e-10
#: For n > KRONECKER_MAX_N the shifted power iteration of the homogeneous modified Riccati map stops after this
#: many steps (below it, 30 steps and then a policy iteration); its answer is a candidate, checked either way.
HOMOGENEOUS_RICCATI_MAX_ITER = 5000
__all__ += ["LEAST_RADIUS_ATOL"]

#: The least mean-square radius min_K rho(L_K) (simulation/region.py) is zero to rounding where the homogeneous
#: Riccati map's power iteration finds tr R(P) <= LEAST_RADIUS_ATOL ||A||_2^2 tr P: an absolute floor scaled to the
#: plant (R(P) = A'PA - ... is a difference of terms of size ||A||^2 ||P||, and iterating on R(P) / lambda below it
#: amplifies their rounding: the last iterate's P carries eigenvalues of eps ||A||^2 / lambda, -8e-7 at lambda 1e-10).
#: The point stops there and reports tr R(P) / tr P, in [0, LEAST_RADIUS_ATOL ||A||_2^2] by that test. Where the
#: always-delivered channels alone reach the state, the least radius is exactly 0 (their deadbeat law) and is
#: reported so: measured before that rule at two such points, the iteration's own value was 0 and 5.2e-32 under the
#: Haswell kernel, 1.17e-12 and 5.99e-12 (4.7e-12 and 5.4e-12 ||A||^2) under Prescott, from P's rounding-level
#: eigenvalues that its PSD part keeps.
LEAST_RADIUS_ATOL = 1e-12

__all__ += ["CHAIN_FORM_RTOL", "ROUNDING_ORDER_RTOL"]

#: Two computations of one quantity that exact arithmetic makes equal and that differ only in the order of their
#: floating-point operations (a stack of matrices against each matrix alone, a gathered update against one written
#: in place, 1/s against a 1 x 1 pseudo-inverse, one (S n) x n product against S small ones, a filter loop against
#: its vectorised form) agree within ROUNDING_ORDER_RTOL times the quantity's largest entry. Bit for bit is not a
#: contract between them: the BLAS kernel picks the order of each product's sums (OpenBLAS's Prescott kernel rounds
#: a stack of 3 x 3 updates up to 1.2e-15 of its scale away from the same updates gathered, where Haswell and
#: SkylakeX agree to the bit). Measured on the tests that compare such pairs under OpenBLAS's Prescott, Nehalem,
#: Sandybridge, Haswell, Zen, SkylakeX and native kernels: at most 1.2e-15 (tests/sensing/test_sensing_estimation.py,
#: tests/sensing/test_sensing_montecarlo_loop.py); equal to the bit (tests/closedloop/test_closed_loop.py's stack of
#: laws, tests/model/test_model.py's repaired weights, tests/qp/test_qp_shared.py's objective against cvxpy's
#: evaluation).
#: 1e-12 leaves room for longer chains of products.
ROUNDING_ORDER_RTOL = 1e-12

__all__ += ["COUPLED_BRACKET_RTOL", "COUPLED_POLICY_REGULARISATION", "COUPLED_ZERO_RTOL"]

#: simulation.markov_region's least radius behind a chain (benchmarks/chain_region_tolerances.py measures all three,
#: on 313 seeded chains: 160 random, pendulum_bursty at 9 mean rates, 24 "current" chains, 120 at the ends of their
#: mean rates). Its power iteration and policy iteration run on ``R + eps Pi`` (``Pi(P)_a = (sum_b tr P_b) I / (M n)``,
#: rho(Pi) = 1), ``eps = COUPLED_POLICY_REGULARISATION lambda``, so that the eigenvector is positive definite and the
#: gains are defined where R's vanishes. Measured, lambda pinned to 1e-9 by its certificate and its gains' radius:
#: 312 of 313 for eps from 1e-14 to 1e-10, 311 at 1e-8 and at 0, 310 and one undecided at 1e-6 (the gains on R's
#: support are off by O(eps / weight), their radius by its square; below 1e-10 nothing changes, above it the
#: regularised parts start to matter).
COUPLED_POLICY_REGULARISATION = 1e-10
#: R(P) is zero to rounding (R nilpotent: least radius exactly 0) where ``sum_a tr R(P)_a <= COUPLED_ZERO_RTOL^2
#: ||A||^2 sum_a tr P_a``. Measured over the first M n + 1 steps of R from I: at most 1.2e-15 (the square root of
#: that ratio) on 412 points whose least radius is 0 (400 random controllable plants behind chains that deliver
#: everything after the first step, 12 two_actuator points with a channel at mean rate 1), at least 0.058 on 400
#: random chains; the same to the digits printed under Haswell, Prescott, Nehalem, Sandybridge, Zen and SkylakeX.
COUPLED_ZERO_RTOL = 1e-12
#: Its checkpoints stop where the gains' radius and the eigenvector's Collatz-Wielandt bound agree to
#: COUPLED_BRACKET_RTOL relative (the least radius is then pinned between them). Measured at the first checkpoint
#: (30 power steps) on the 313 chains: median 8e-16, 99 % 9.3e-12, largest 4.9e-11 (Haswell; Prescott 2.1e-11).
COUPLED_BRACKET_RTOL = 1e-10

# ------------------------------------------------------------------ the actuator on a loss (closedloop/actuator.py)
__all__ += ["ACTUATOR_COMPARE_TOL", "ACTUATOR_CRITICAL_MU_ATOL", "ACTUATOR_DP_RTOL", "ACTUATOR_DP_STATIONARY_RTOL",
            "ACTUATOR_EXACT_RTOL", "ACTUATOR_ZERO_RTOL",
            "SAMPLED_Z_MAX"]
#: "zero" is today's loop: the same engine call on the same arrays, so its radius and costs agree with
#: closedloop.stability / moments / mjls to this (measured: 0, bit for bit, on four channels under Haswell, Prescott and
#: SkylakeX kernels).
ACTUATOR_ZERO_RTOL = 1e-12
#: The engine's exact costs of hold and buffer:L against the enumeration of every delivery path (and the same
#: quantity computed through another mode structure: buffer:1 against zero; the hand moment recursions of the scalar
#: plant; ARPACK's radius against the dense eigenvalues) (measured: at most 1.1e-15 against enumeration, 2.3e-15
#: buffer:1 against zero, 1.5e-15 at mu = 1, 6.6e-15 Krylov against dense on 16 to 576 rows, 6.0e-15 the buffer's
#: predicted-state memory against its entries, on plants of n <= 2 with 1 to 63 modes, under Haswell, Prescott and
#: SkylakeX kernels; ARPACK's radii of the two memories of a 162-mode buffer agree to 3.5e-14, within ARPACK_TOL).
ACTUATOR_EXACT_RTOL = 1e-12
#: The critical mu of a scalar loop found where the engine's radius crosses 1, against the hand renewal closed form's
#: root, both by brentq to xtol 1e-14 (measured: at most 2.0e-15 over three plants and four strategies, under Haswell,
#: Prescott and SkylakeX kernels).
ACTUATOR_CRITICAL_MU_ATOL = 1e-12
#: The optimal law per strategy (closedloop/actuator_design.py) against its references: the enumerated optimum over
#: every delivery path, the channel's own DP for zero, hand values (measured: at most 2.5e-15 against enumeration,
#: 6.3e-16 against dp_riccati and coupled_riccati, under Haswell, Prescott and SkylakeX kernels).
ACTUATOR_DP_RTOL = 1e-12
#: Two stationary optima of the same equation, each iterated until ``||P_next - P|| <= RICCATI_RTOL ||P||``, agree to
#: a few RICCATI_RTOL times the loop's slowness (measured: 1.8e-12 relative on the pendulum's x0'P x0, radius
#: 0.98, zero's optimum against dp_riccati; 2e-16 on two_actuator).
ACTUATOR_DP_STATIONARY_RTOL = 1e-10
#: The width in t of the bracket of a strategy's critical mu on the command line (compare, region --actuator): each
#: halving is a power iteration of the homogeneous map (hold on two_actuator: about 13 s at 1e-4).
ACTUATOR_COMPARE_TOL = 1e-4
#: A sampled mean agrees with its exact expectation when within this many standard errors (two-sided normal tail
#: 6.8e-6 per check).
SAMPLED_Z_MAX = 4.5
