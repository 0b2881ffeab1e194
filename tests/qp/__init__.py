"""Tests of the solver twin: the expected-cost QPs, their backends and cross-checks."""
