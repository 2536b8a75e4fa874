"""One thread per math library in the processes that step simulations.

numpy and scipy each load their own OpenBLAS; each starts a pool of threads (one per core)
at import and, after a matrix call, lets them spin for a while before they sleep. The
loop is single-threaded and its matrices are tiny (a score's least squares, a 2x2 solve
of an observer), so the pools do no useful work -- but on a machine with as many busy
processes as cores (a campaign's workers, one per core) their spinning takes the other
worker's core: ``perf`` showed ``blas_thread_server`` at 6 % of a run (docs/performance.md).

The thread counts are read once, when the library loads: :func:`one_thread_per_math_library`
must run before numpy is imported in the process, or before the process that will import
it is started (its environment is inherited). A value the user set is kept.
"""
from __future__ import annotations

import os

# OpenBLAS (numpy's and scipy's wheels), OpenMP (an OpenBLAS or MKL built with it), MKL
THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def one_thread_per_math_library(environ=None) -> dict[str, str]:
    """Set every variable of :data:`THREAD_VARIABLES` that is not set to ``"1"`` in
    ``environ`` (default ``os.environ``); returns the ones it set."""
    env = os.environ if environ is None else environ
    chosen = {name: "1" for name in THREAD_VARIABLES if name not in env}
    env.update(chosen)
    return chosen
