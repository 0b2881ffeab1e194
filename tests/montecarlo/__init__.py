"""Tests of sampling the model and the loop: simulate, Markov loops, tails."""
