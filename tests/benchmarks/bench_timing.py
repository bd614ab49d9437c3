"""Timing for the side-by-side benchmark (``tests.benchmarks.bench``): fresh processes with a time
cap, and the chosen settings of every engine timed in turn, so the ratios come from the same
run under the same load.

Each timed run is one fresh process (``fresh``: spawned, so peak memory and first-call costs are
its own) doing a *cold* run, then a *warm* run of the same setting:

* first call [s]: what the cold run costs beyond the warm one (importing the engine's library,
  numba's disk-cache load or compile of the kernels, first-call caches);
* set-up [s]: the warm run's engine reset (model building; the TMM: factorization of one
  revolution of configurations and its quasi-static start);
* marching [s per simulated s]: the warm run's engine time after its reset.
"""
from __future__ import annotations

import multiprocessing as mp
import resource
import time
import traceback

import numpy as np

FRESH = True       # measure in fresh processes (the --tiny run of the test suite stays in-process)


class CapExceeded(RuntimeError):
    """A fresh process did not finish within its time cap (it was stopped)."""


def _child(conn, fn, args):
    try:
        conn.send(("ok", fn(*args)))
    except BaseException as exc:          # report any failure to the parent, then exit
        conn.send(("error", f"{type(exc).__name__}: {exc}\n{traceback.format_exc(limit=3)}"))
    finally:
        conn.close()


def fresh(fn, *args, cap_s: float | None = None):
    """``fn(*args)`` in a fresh (spawned) process; raises CapExceeded after ``cap_s`` seconds (the
    process is stopped), RuntimeError if it fails or dies. In-process when FRESH is False."""
    if not FRESH:
        return fn(*args)
    ctx = mp.get_context("spawn")
    parent, child = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(child, fn, args), daemon=True)
    proc.start()
    child.close()
    finished = False
    try:
        if not parent.poll(cap_s):
            raise CapExceeded(f"not finished in {cap_s:.0f} s")
        finished = True
        status, value = parent.recv()
    except EOFError:
        proc.join(10)
        raise RuntimeError(f"the benchmark process died (exit code {proc.exitcode})") from None
    finally:
        proc.join(10 if finished else 0)
        if proc.is_alive():
            proc.kill()                    # only the process started here
            proc.join(10)
        parent.close()
    if status != "ok":
        raise RuntimeError(value)
    return value


def timed_process(rig: str, engine: str, setting: dict, revolutions: float, cold_revolutions: float) -> dict:
    """A cold run of ``cold_revolutions`` and a warm run of ``revolutions`` in this process.

    Returns {"first_call_s", "setup_s", "march_s", "sim_s" (warm run, [s]), "cold_s" (cold run,
    engine creation included [s]), "maxrss_kB"}."""
    from cosim.engines import make_engine
    from cosim.master import run_prescribed
    from .bench_accuracy import scenario_for, timed
    sc = scenario_for(rig, engine, setting)

    def one(revs):
        tic = time.perf_counter()
        eng = make_engine(engine)          # the cold run pays the library's import here
        setup = [0.0]
        eng.reset = timed(eng.reset, setup)
        run = run_prescribed(eng, sc, revolutions=revs)
        return time.perf_counter() - tic, setup[0], run.wall_time_s, float(run.t[-1])
    cold, _, _, _ = one(cold_revolutions)
    total, setup, wall, sim = one(revolutions)
    march = wall - setup
    # The cold run's expected cost without first calls: the warm set-up plus its share of marching.
    first = cold - (total - wall) - (setup + march * cold_revolutions / revolutions)
    return {"first_call_s": first, "setup_s": setup, "march_s": march, "sim_s": sim, "cold_s": cold,
            "maxrss_kB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss}


def periodic_solve(rig: str, setting: dict) -> float:
    """Wall time [s] of the TMM's periodic steady-state solve at ``setting`` (after a first call)."""
    from cosim.sweeps import periodic_solution
    from .bench_accuracy import scenario_for
    sc = scenario_for(rig, "tmm", setting)
    tic = time.perf_counter()
    periodic_solution(sc)
    return time.perf_counter() - tic


def time_chosen(rig: str, chosen: dict, repeats: int, revolutions: float, cold_revolutions: float,
                periodic_cap_s: float | None) -> dict:
    """Time every engine's chosen setting: ``repeats`` rounds, each engine once per round (fresh
    processes), so the engines share the machine's load. ``chosen``: {engine: {"setting",
    "revolutions_to_steady", ...}}. Returns {engine: timing} with medians and every run."""
    runs = {e: [] for e in chosen}
    errors = {}
    for _ in range(repeats):
        for engine, c in chosen.items():
            if engine in errors:
                continue
            try:
                runs[engine].append(fresh(timed_process, rig, engine, c["setting"], revolutions, cold_revolutions))
            except Exception as exc:
                errors[engine] = f"{type(exc).__name__}: {exc}"
    out = {}
    for engine, rs in runs.items():
        if not rs:
            out[engine] = {"error": errors.get(engine, "no run")}
            continue

        def med(key):
            return float(np.median([r[key] for r in rs]))
        sim = med("sim_s")
        row = {"first_call_s": med("first_call_s"), "setup_s": med("setup_s"),
               "march_per_sim_s": float(np.median([r["march_s"] / r["sim_s"] for r in rs])),
               "wall_per_sim_s": float(np.median([(r["setup_s"] + r["march_s"]) / r["sim_s"] for r in rs])),
               "timed_revolutions": revolutions, "peak_memory_MB": med("maxrss_kB") / 1024.0, "runs": rs}
        revs = chosen[engine].get("revolutions_to_steady")
        period = sim / revolutions
        row["time_to_steady_s"] = None if revs is None else row["setup_s"] + revs * period * row["march_per_sim_s"]
        if engine in errors:
            row["error"] = errors[engine]
        out[engine] = row
    if "tmm" in out and "error" not in out["tmm"] and periodic_cap_s != 0:
        try:
            out["tmm"]["periodic_solve_s"] = fresh(periodic_solve, rig, chosen["tmm"]["setting"], cap_s=periodic_cap_s)
        except CapExceeded as exc:
            out["tmm"]["periodic_solve_s"] = str(exc)
        except Exception as exc:          # e.g. its maps exceed the memory budget at fine steps
            out["tmm"]["periodic_solve_s"] = f"failed: {str(exc).splitlines()[0]}"
    return out


def ratios(timing: dict) -> dict:
    """Each engine's costs over the TMM's (dimensionless): marching per simulated second, set-up
    plus marching per simulated second, time to the steady state."""
    t = timing.get("tmm") or {}
    out = {}
    for engine, row in timing.items():
        if engine == "tmm" or "march_per_sim_s" not in row or "march_per_sim_s" not in t:
            continue
        r = {"march": row["march_per_sim_s"] / t["march_per_sim_s"],
             "wall": row["wall_per_sim_s"] / t["wall_per_sim_s"]}
        if row.get("time_to_steady_s") and t.get("time_to_steady_s"):
            r["to_steady"] = row["time_to_steady_s"] / t["time_to_steady_s"]
        out[engine] = r
    return out
