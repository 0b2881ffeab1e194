"""Tests of the command line: subcommands, parser, reference, reproduce, imports, kernels."""
