"""Tests of channel allocation: M*, certificates, chains, power, stability-aware targets."""
