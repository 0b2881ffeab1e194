"""Tests of the open-loop Theorem-1 pipeline: closed forms, the recursion, evaluators, Markov exact costs."""
