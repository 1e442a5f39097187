"""Benchmarks and experiment drivers: run by `make bench`, `make trials`, `make demo-check`."""
