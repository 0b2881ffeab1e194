"""The solver twin: the expected-cost minimisations posed as cvxpy problems and solved with Clarabel.

``convex`` (running cvxpy problems under one policy), ``expected_cost`` (``ExpectedCostQP``, ``solve_qp`` and
the cross-check against the closed form), ``shared`` (the condensed QP compiled once per padded shape),
``markov`` (the same under Markov losses). Modules here import cvxpy; the closed-form paths never import them.
"""
