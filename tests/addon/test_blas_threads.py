"""One BLAS thread in a batch's processes: the workers' environment, and the OpenBLAS
libraries already loaded in the batch's own process."""

import sys

import pytest

from headrecon_addon import blas_threads


def test_environment_sets_one_thread_and_keeps_the_callers_choice():
    assert blas_threads.environment({}) == {v: "1" for v in blas_threads.VARIABLES}
    env = blas_threads.environment({"OPENBLAS_NUM_THREADS": "4"})
    assert env["OPENBLAS_NUM_THREADS"] == "4" and env["OMP_NUM_THREADS"] == "1"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/maps")
def test_limit_loaded_sets_every_loaded_openblas(monkeypatch):
    import scipy.linalg  # noqa: F401  (scipy's own OpenBLAS, as the solver loads it)

    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    before = blas_threads.loaded_threads()
    assert len(before) >= 2  # numpy's and scipy's
    try:
        for path in before:  # start from two threads, whatever the machine has
            blas_threads._function(path, blas_threads._SETTERS)(2)
        assert set(blas_threads.limit_loaded()) == set(before)
        assert set(blas_threads.loaded_threads().values()) == {1}
        monkeypatch.setenv("OPENBLAS_NUM_THREADS", "2")  # the environment's choice stands
        for path in before:
            blas_threads._function(path, blas_threads._SETTERS)(2)
        assert blas_threads.limit_loaded() == []
        assert set(blas_threads.loaded_threads().values()) == {2}
    finally:
        for path, n in before.items():
            blas_threads._function(path, blas_threads._SETTERS)(n)
