"""Benchmarks (speed and memory), run by the Makefile targets; never imported by the CLI."""
