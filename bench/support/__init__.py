"""Harnesses shared by the benchmarks and the test suite: known-answer vendor files, DTW inputs, the emulated
acceptance run and where the shared mocap lives. Here, not in `tests/`, so the benches never import the test
package and `tests` need not be installed; the suite imports them from here too (one definition each)."""
