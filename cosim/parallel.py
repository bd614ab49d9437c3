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
        pool = ProcessPoolExecutor(max_workers=workers or os.cpu_count() or 1)
        try:
            yield pool
        finally:
            pool.shutdown(cancel_futures=True)


def describe(scheduler: str | None) -> str:
    return f"dask {scheduler}" if scheduler else "local processes"
