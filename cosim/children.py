"""A command's child processes, ended: no child outlives the command that started it.

Owns: ending a child process (:func:`stop_process`). Boundaries: starting them is their owners'
(the kernel warm-up, the recording process, the viewer servers); a process pool's workers are
cosim.parallel's. Imports the standard library only: the command line's start-up loads it.
"""
from __future__ import annotations

import subprocess


def stop_process(process: subprocess.Popen, grace_s: float) -> None:
    """End a child process: SIGTERM first (a child may finish its file on it), SIGKILL if it has not
    ended within ``grace_s`` [s]; reaped either way. Nothing to do for one that has ended."""
    if process.poll() is not None:
        return
    process.terminate()
    try:
        process.wait(timeout=grace_s)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()
