"""Benchmarks, apart from the tests (`experiments.bench.__main__` lists the targets)."""
