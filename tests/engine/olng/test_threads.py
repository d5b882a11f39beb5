"""The per-step BLAS limit (engine/olng/threads.py) holds OpenBLAS to one thread inside and restores it after."""
import numpy as np
import pytest

from engine.olng.threads import single_blas_thread

threadpoolctl = pytest.importorskip("threadpoolctl")


def _blas_threads() -> list[int]:
    return [info["num_threads"] for info in threadpoolctl.threadpool_info() if info["user_api"] == "blas"]


def test_one_thread_inside_and_restored_after() -> None:
    np.linalg.eigh(np.eye(4))  # BLAS loaded
    before = _blas_threads()
    assert before, "numpy's BLAS should be visible to threadpoolctl"
    one_thread = single_blas_thread()
    with one_thread():
        assert _blas_threads() == [1] * len(before)
    assert _blas_threads() == before
