"""The model: what a user describes and the package validates before any work.

The plant, weights, horizon and initial state (``system``), the links (``channel``: Gilbert–Elliott,
``markov_channel``: k-state chains, ``chain``: the delivery statistics and belief filter a chain implies),
the sensors (``sensor``), the one validator of numeric input (``validation``), the protocols' names
(``protocols``), system files and the shipped examples (``files``, ``examples``), python-control interop
(``statespace``) and seeded random systems (``random_systems``). Everything here is frozen once built and
computes nothing about control: the layers above take a validated :class:`~packetloss_cvx.model.system.System`.
"""
