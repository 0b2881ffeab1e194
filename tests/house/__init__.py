"""Tests of the house rules and infrastructure: architecture, namespace, packaging, files, budgets, hostile input."""
