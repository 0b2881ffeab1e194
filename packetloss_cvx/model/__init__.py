"""The model: what a user describes and the package validates before any work.

The plant, weights, horizon and initial state (``system``), the links (``channel``: the one channel type, k-state Markov
chains, with Gilbert–Elliott and Bernoulli as its constructors; ``chain``: the delivery statistics and belief filter a
chain implies; ``twins``: a system's bursty twins),
the sensors (``sensor``), the one validator of numeric input (``validation``), the protocols' names
(``protocols``), system files and the shipped examples (``files``, ``examples``), python-control interop
(``statespace``) and seeded random systems (``random_systems``). Everything here is frozen once built and
computes nothing about control: the layers above take a validated [`System`][packetloss_cvx.model.system.System].
"""
