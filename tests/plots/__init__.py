"""Tests of figures and their style."""
