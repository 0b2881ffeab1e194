"""Tests of the documentation: pages, doctests, README, the equation index."""
