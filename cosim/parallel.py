"""One executor interface for independent jobs (sweep points, uncertainty samples): a process pool
on the local cores, or a Dask distributed cluster given its scheduler address. Both hand out
``concurrent.futures`` futures, so callers do not care which one runs them.

Owns: one executor interface (local processes or Dask). Boundaries: no job logic.
"""
from __future__ import annotations

import functools
import math
import os
import signal
import threading
import time
from concurrent.futures import Future, ProcessPoolExecutor
from contextlib import contextmanager


#: A local pool given its job count splits the jobs into this many blocks per worker: each block
#: continues over ~20 speeds of an 81-point sweep on 2 workers (a block's first speed starts
#: cold, 2-3x dearer), and the worker that finishes first takes the next block, so the blocks
#: near buckling (2-3x dearer per point) do not leave one worker running alone for long.
BLOCKS_PER_WORKER = 2


@contextmanager
def executor(workers: int | None = None, scheduler: str | None = None, jobs: int | None = None):
    """``with executor(workers, scheduler) as ex: ex.submit(fn, *args)``. ``jobs``: the number of
    jobs the caller will submit, in an order where neighbours belong together (a sweep's speeds):
    the local pool then runs them in contiguous blocks (:class:`BlockPool`), so that a worker can
    start each job from its previous one's result. Dask ignores it."""
    if scheduler:
        from distributed import Client
        client = Client(scheduler)
        try:
            yield client.get_executor()
        finally:
            client.close()
        return
    count = workers or os.cpu_count() or 1
    pool = ProcessPoolExecutor(max_workers=count, initializer=start_worker, initargs=(os.getpid(),))
    try:
        yield BlockPool(pool, jobs, count * BLOCKS_PER_WORKER) if jobs else pool
    except BaseException:
        # Interrupted or failed: the jobs still running are of no use, and a long one (an
        # identification start) would hold the exit for a minute.
        terminate_workers(pool)           # first: shutdown() forgets the pool's processes
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    finally:
        pool.shutdown(cancel_futures=True)


class BlockPool:
    """A process pool that runs ``jobs`` submissions in contiguous blocks: the submissions are
    split in submission order into ``blocks`` runs of consecutive jobs, each run in one worker
    process in order (a sweep's worker continues from speed to speed), and once the last job is
    submitted the blocks go to the pool last block first (a sweep's dearest speeds, near
    buckling, start first and the cheap ones fill the workers' remaining time). Each job still
    has its own future, set when its block finishes."""

    def __init__(self, pool: ProcessPoolExecutor, jobs: int, blocks: int):
        self.pool, self.jobs = pool, max(int(jobs), 1)
        self.size = math.ceil(self.jobs / max(int(blocks), 1))
        self.pending: list = []

    def submit(self, fn, *args) -> Future:
        future = Future()
        self.pending.append((future, fn, args))
        if len(self.pending) == self.jobs:
            runs = [self.pending[k:k + self.size] for k in range(0, self.jobs, self.size)]
            for run in reversed(runs):
                block = self.pool.submit(run_block, [(fn, args) for _, fn, args in run])
                block.add_done_callback(functools.partial(_settle, [f for f, _, _ in run]))
        return future


def run_block(calls: list) -> list:
    """``[(fn, args), ...]`` run in order in this worker: ``[(True, result) or (False, error)]``
    (one job's error does not stop the block)."""
    out = []
    for fn, args in calls:
        try:
            out.append((True, fn(*args)))
        except Exception as exc:          # reported on that job's future
            out.append((False, exc))
    return out


def _settle(futures: list, block: Future) -> None:
    """Each job's future from its block's: result or error per job; the block's own error (a
    worker that died) or cancellation on every job of it."""
    if block.cancelled():
        for f in futures:
            f.cancel()
        return
    error = block.exception()
    for k, f in enumerate(futures):
        if error is not None:
            f.set_exception(error)
            continue
        ok, value = block.result()[k]
        f.set_result(value) if ok else f.set_exception(value)


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
