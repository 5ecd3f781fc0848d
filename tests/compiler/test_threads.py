"""Threads are chosen on purpose: never the TBB layer unless the user asks for it, one
thread for small problems, and IPCSIM_THREADS fixes the count."""

from __future__ import annotations

import os
import subprocess
import sys

import numba
import pytest

from ipcsim.compiler import threads


def test_the_layer_is_never_tbb_by_default():
    if "NUMBA_THREADING_LAYER" in os.environ:
        pytest.skip("the user chose a layer")
    from ipcsim.compiler.jit import numba_module

    assert threads.choose_layer(numba_module()) in ("omp", "workqueue")


def test_a_fresh_process_runs_a_parallel_kernel_on_the_chosen_layer():
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_THREADING_LAYER"}
    code = ("import numpy as np, numba\n"
            "from ipcsim.compiler import threads\n"
            "from ipcsim.kernels.contact import broad_phase as bp\n"
            "threads.run_parallel(True)\n"
            "x = np.random.default_rng(0).random((50, 3))\n"
            "bp.primitive_boxes(x, x, np.arange(50).reshape(-1, 1), 0.1)\n"
            "print(numba.threading_layer())\n")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, check=True).stdout.split()
    assert out[-1] in ("omp", "workqueue")


def test_small_problems_run_on_one_thread(monkeypatch):
    monkeypatch.delenv("IPCSIM_THREADS", raising=False)
    assert threads.threads_for(threads.PARALLEL_FROM_VERTICES - 1) == 1
    big = threads.threads_for(10 * threads.PARALLEL_FROM_VERTICES)
    assert 1 <= big <= numba.config.NUMBA_NUM_THREADS


def test_ipcsim_threads_fixes_the_count(monkeypatch):
    monkeypatch.setenv("IPCSIM_THREADS", "1")
    assert threads.threads_for(10 * threads.PARALLEL_FROM_VERTICES) == 1
    monkeypatch.setenv("IPCSIM_THREADS", "many")
    with pytest.warns(UserWarning, match="not a positive integer"):
        threads.threads_for(10)


def test_both_variants_of_a_kernel_give_the_same_bits():
    """The serial and the parallel variant are one source; per-item results are written
    to their own slots and summed in order, so both give bitwise equal answers."""
    import numpy as np

    from ipcsim.kernels.contact import pair_barrier as cb

    rng = np.random.default_rng(5)
    x = rng.random((400, 3))
    pt = rng.permutation(400).reshape(-1, 4)[:60].astype(np.int64)
    ee = rng.permutation(400).reshape(-1, 4)[:40].astype(np.int64)
    eps = np.full(len(ee), 1e-3)
    results = []
    for parallel in (False, True):
        threads.run_parallel(parallel)
        try:
            results.append((cb.barrier_value(x, pt, ee, eps, 0.09, 1.0),
                            cb.barrier_gradient(x, pt, ee, eps, 0.09, 1.0),
                            cb.barrier_hessian_triplets(x, pt, ee, eps, 0.09, 1.0, True)[2]))
        finally:
            threads.run_parallel(False)
    (v0, g0, h0), (v1, g1, h1) = results
    assert v0 == v1 and v0 > 0.0
    np.testing.assert_array_equal(g0, g1)
    np.testing.assert_array_equal(h0, h1)


@pytest.mark.skipif(not os.path.isdir("/proc/self/task"), reason="needs Linux's /proc")
def test_the_command_line_keeps_numpys_blas_on_one_thread_unless_told_otherwise():
    # importing ipcsim.cli loads numpy: its OpenBLAS starts no idle worker to spin
    code = ("import os, ipcsim.cli\n"
            "print(os.environ['OPENBLAS_NUM_THREADS'], len(os.listdir('/proc/self/task')))\n")
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, check=True).stdout.split()
    assert out == ["1", "1"]
    out = subprocess.run([sys.executable, "-c", code],
                         env=env | {"OPENBLAS_NUM_THREADS": "3"}, capture_output=True,
                         text=True, check=True).stdout.split()
    assert out[0] == "3"  # the user's setting wins
