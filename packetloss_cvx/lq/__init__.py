"""The open-loop Theorem-1 mathematics: expected costs of plans and their minimisers in closed form.

``prediction`` (the stacked Phi, Gamma, Omega products), ``recursion`` (the O(N) backward recursion and the
forward referee), ``costs`` (``closed_form``, ``expected_cost``: the method choice and the dense kernels),
``evaluator`` and ``pointwise`` (J*(mu) over many channels, or one at a time), ``roundoff`` (rounding bounds
of a rolled-out plan), ``difference`` (J_Delta between the protocols, Lemmas 2–3, Theorem 4), ``analysis``
(Theorem 3, Tables I–II), and the same under Markov losses: ``markov_cost`` (the exact expected cost and
its minimiser) and ``augmented`` (that cost as an LQ problem on the augmented state).
"""
