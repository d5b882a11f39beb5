"""Benchmarks (run as scripts: `python bench/bench_X.py`) and `bench.support`, the harnesses they share with the
tests. A plain folder beside `tests/`, never installed: the wheel ships only the product packages."""
