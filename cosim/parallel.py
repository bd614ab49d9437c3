"""One executor interface for independent jobs (sweep points, uncertainty samples): a process pool
on the local cores, or a Dask distributed cluster given its scheduler address. Both hand out
``concurrent.futures`` futures, so callers do not care which one runs them.

Owns: one executor interface (local processes or Dask). Boundaries: no job logic.
"""
from __future__ import annotations

import os
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager


@contextmanager
def executor(workers: int | None = None, scheduler: str | None = None):
    """``with executor(workers, scheduler) as ex: ex.submit(fn, *args)``."""
    if scheduler:
        from distributed import Client
        client = Client(scheduler)
        try:
            yield client.get_executor()
        finally:
            client.close()
    else:
        pool = ProcessPoolExecutor(max_workers=workers or os.cpu_count() or 1, initializer=one_thread_per_worker)
        try:
            yield pool
        finally:
            pool.shutdown(cancel_futures=True)


def one_thread_per_worker() -> None:
    """Worker start: one BLAS thread and one compiled-kernel thread per worker process. The
    workers already fill the cores; threads on top of them oversubscribe the machine, and the
    small dense solves of a periodic solve then slow down by orders of magnitude (measured on 2
    cores, two workers: six 216 x 216 eigenvalue problems 3.8 s with OpenBLAS's default threads,
    0.03 s with one)."""
    from threadpoolctl import threadpool_limits
    threadpool_limits(1, user_api="blas")
    from tmm_core import kernels_static
    kernels_static.THREADS = 1


def describe(scheduler: str | None) -> str:
    return f"dask {scheduler}" if scheduler else "local processes"
