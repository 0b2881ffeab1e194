"""The open-loop Theorem-1 mathematics: expected costs of plans and their minimisers in closed form.

One pipeline, top down: ``costs`` (the API: ``closed_form``, ``expected_cost``) -> ``policy`` (the one method
chooser and the one self-check against the forward cost) -> the kernels ``dense`` (the dense closed form, its
constant term written once) and ``recursion`` (the O(N) backward recursion, the rollout and the forward referee)
-> ``structure`` (what does not depend on mu or x0, built once per system structure and kept in its own store),
``prediction`` (the stacked Phi, Gamma, Omega products) and ``settling`` (whether an iterate has settled).
Beside it:
``evaluator`` and ``pointwise`` (J*(mu) over many channels, or one at a time), ``roundoff`` (rounding bounds
of a rolled-out plan), ``difference`` (J_Delta between the protocols, Lemmas 2–3, Theorem 4), ``analysis``
(Theorem 3, Tables I–II), and the same under Markov losses: ``markov_cost`` (the exact expected cost and
its minimiser) and ``augmented`` (that cost as an LQ problem on the augmented state).
"""
