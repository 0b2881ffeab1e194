"""Tests of the audit of the paper's claims and its document."""
