"""One executor interface for independent jobs (sweep points, uncertainty samples): a process pool
on the local cores, or a Dask distributed cluster given its scheduler address. Both hand out
``concurrent.futures`` futures, so callers do not care which one runs them.

Owns: one executor interface (local processes or Dask). Boundaries: no job logic.
"""
from __future__ import annotations

import os
import signal
import threading
import time
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager


@contextmanager
def executor(workers: int | None = None, scheduler: str | None = None, jobs: int | None = None):
    """``with executor(workers, scheduler) as ex: ex.submit(fn, *args)``. ``jobs``: the number of
    jobs the caller will submit, in an order where neighbours belong together (a sweep's speeds):
    the local pool then hands them to its workers in contiguous blocks (:class:`BlockPool`), so
    that a worker can start each job from its previous one's result. Dask ignores it."""
    if scheduler:
        from distributed import Client
        client = Client(scheduler)
        try:
            yield client.get_executor()
        finally:
            client.close()
        return
    count = workers or os.cpu_count() or 1
    pools = [_local_pool(1) for _ in range(count)] if jobs else [_local_pool(count)]
    try:
        yield BlockPool(pools, jobs) if jobs else pools[0]
    except BaseException:
        # Interrupted or failed: the jobs still running are of no use, and a long one (an
        # identification start) would hold the exit for a minute.
        for pool in pools:
            terminate_workers(pool)           # first: shutdown() forgets the pool's processes
            pool.shutdown(wait=False, cancel_futures=True)
        raise
    finally:
        for pool in pools:
            pool.shutdown(cancel_futures=True)


def _local_pool(workers: int) -> ProcessPoolExecutor:
    return ProcessPoolExecutor(max_workers=workers, initializer=start_worker, initargs=(os.getpid(),))


class BlockPool:
    """Local worker processes, each with its own single-process pool, that take ``jobs``
    submissions in contiguous blocks: the k-th job goes to worker ``k * workers // jobs``, and a
    worker runs its jobs in submission order (a sweep's worker continues from speed to speed).
    The blocks are as even as the count allows; a worker whose block is dearer (near buckling)
    finishes later, the price of continuation."""

    def __init__(self, pools: list, jobs: int):
        self.pools, self.jobs, self.submitted = pools, max(int(jobs), 1), 0

    def submit(self, fn, *args):
        worker = min(self.submitted * len(self.pools) // self.jobs, len(self.pools) - 1)
        self.submitted += 1
        return self.pools[worker].submit(fn, *args)


def terminate_workers(pool: ProcessPoolExecutor) -> None:
    """End a local pool's worker processes now, with SIGKILL: they hold no files, and a worker
    forked a moment ago may still carry its parent's SIGTERM handler (a KeyboardInterrupt and a
    traceback). Python 3.14 has ``ProcessPoolExecutor.kill_workers`` for this; before it, the
    pool's process table is the only handle on its workers."""
    if hasattr(pool, "kill_workers"):
        pool.kill_workers()
        return
    procs = list((getattr(pool, "_processes", None) or {}).values())
    for proc in procs:
        if proc.is_alive():
            proc.kill()
    for proc in procs:
        proc.join(timeout=5.0)


def start_worker(parent_pid: int) -> None:
    """Worker start: the worker leaves the parent's Ctrl-C to the parent, ends when the parent is
    gone, and uses one thread for BLAS and the compiled kernels.

    * SIGINT ignored, SIGTERM the default: a Ctrl-C in the terminal reaches the whole process
      group; the parent decides (it cancels the jobs and ends the workers), and no worker prints
      a traceback.
    * A watchdog thread ends the worker once its parent has died (SIGKILL of the parent leaves
      no one to end it, and an idle worker would wait on its job queue forever).
    * One thread: the workers already fill the cores; threads on top of them oversubscribe the
      machine, and the small dense solves of a periodic solve then slow down by orders of
      magnitude (measured on 2 cores, two workers: six 216 x 216 eigenvalue problems 3.8 s with
      OpenBLAS's default threads, 0.03 s with one)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)       # the parent's handler raises KeyboardInterrupt
    threading.Thread(target=_exit_with_parent, args=(parent_pid,), daemon=True, name="parent-watch").start()
    from threadpoolctl import threadpool_limits
    threadpool_limits(1, user_api="blas")
    from tmm_core.compiled import statics as compiled_statics
    compiled_statics.THREADS = 1


#: How often a worker checks that its parent is alive [s].
PARENT_POLL_S = 0.5


def _exit_with_parent(parent_pid: int) -> None:
    """Poll the parent; once this process has been re-parented (the parent died), exit at once
    without cleanup (the parent's queues are gone; flushing them would block)."""
    while os.getppid() == parent_pid:
        time.sleep(PARENT_POLL_S)
    os._exit(1)


def describe(scheduler: str | None) -> str:
    return f"dask {scheduler}" if scheduler else "local processes"
