"""The progress of one run, on the console and in summary.json.

A run of fixed length progresses with its macro steps. A run until steady ends when every engine
is steady or at the revolution cap, whichever comes first, so its progress is the larger of the
two: the cap's share of the macro steps, and the slowest engine's way from its first measured
revolution change down to the tolerance, on a log scale (a transient that decays geometrically
per revolution then moves the bar at an even pace). The bar never goes back and ends at 100 %
when the run ends, settled or not.

The remaining time is shown only where it is known: for a fixed length, from the pace of the
macro steps since the first one ended (the set-up and the kernels' compilation are not a pace);
a run until steady shows its revolution change against the tolerance instead.

Owns: the run's progress measure and bar. Boundaries: no engine numerics (the changes come with
each cosim.master.MacroStep), no files.
"""
from __future__ import annotations

import logging
import math
import time

from tmm_core.compiled.cache import COMPILE_ESTIMATE_S, cache_is_cold

log = logging.getLogger(__name__)

#: The bar without tqdm's own remaining time (its rate would include the set-up and compilation).
BAR_FORMAT = "{desc}: {percentage:3.0f}%|{bar}| {elapsed}{postfix}"


def compile_notice(estimate_s: float = COMPILE_ESTIMATE_S) -> str | None:
    """Say so before a run or a study that will compile the transfer-matrix kernels (numba's cache
    is cold): the bar would otherwise sit at 0 % for one to two minutes. ``estimate_s`` [s]: how
    long it takes on a 2-core machine (the time domain's kernels by default; a study that solves
    periodic orbits passes :data:`tmm_core.compiled.cache.PERIODIC_COMPILE_ESTIMATE_S`). Returns
    the message logged."""
    if not cache_is_cold():
        return None
    text = (f"compiling the transfer-matrix kernels (once, about {estimate_s:.0f} s on a 2-core machine; "
            "later runs load them from numba's cache)")
    log.info(text)
    return text


def toward_steady(change: dict, first: dict, tolerance: float) -> float:
    """Share [0, 1] of the way to the steady state: per engine log(first / change) /
    log(first / tolerance) (``first``: its first measured change, ``change``: the latest, both
    relative), the slowest engine's; 0 while an engine has no change measured yet."""
    if not change:
        return 0.0
    shares = []
    for name, c in change.items():
        c0 = first.get(name, c)
        if not (math.isfinite(c) and math.isfinite(c0)):
            shares.append(0.0)
        elif c <= tolerance or c0 <= tolerance:
            shares.append(1.0 if c <= tolerance else 0.0)
        else:
            shares.append(min(1.0, max(0.0, math.log(c0 / c) / math.log(c0 / tolerance))))
    return min(shares)


class RunProgress:
    """Progress of a run's macro steps (:class:`cosim.master.MacroStep`): ``fraction`` [0, 1],
    the remaining time [s] when known, and a tqdm bar when ``bar`` (``desc`` its label)."""

    def __init__(self, until_steady: bool, desc: str = "", bar: bool = False, clock=time.monotonic):
        self.until_steady, self.clock = until_steady, clock
        self.fraction, self.remaining_s = 0.0, None
        self.first_change = {}
        self._first_step = None          # (clock, step) when the first macro step ended
        self.bar = None
        if bar:
            from tqdm import tqdm
            self.bar = tqdm(total=1.0, unit="run", desc=desc, leave=True, disable=None, bar_format=BAR_FORMAT)

    def update(self, step) -> float:
        """Take one macro step; returns the run's fraction done."""
        now = self.clock()
        if self._first_step is None:
            self._first_step = (now, step.step)
        fraction = step.step / step.n_steps
        if self.until_steady and step.change:
            for name, c in step.change.items():
                self.first_change.setdefault(name, c)
            fraction = max(fraction, toward_steady(step.change, self.first_change, step.steady_tolerance))
        self.fraction = max(self.fraction, min(fraction, 1.0))
        self.remaining_s = None if self.until_steady else self._remaining(now, step)
        if self.bar is not None:
            self.bar.update(self.fraction - self.bar.n)
            self.bar.set_postfix_str(self._note(step), refresh=False)
        return self.fraction

    def _remaining(self, now: float, step) -> float | None:
        t1, k1 = self._first_step
        if step.step <= k1 or now <= t1:
            return None
        return (now - t1) / (step.step - k1) * (step.n_steps - step.step)

    def _note(self, step) -> str:
        if self.remaining_s is not None:
            return f"about {_clock(self.remaining_s)} left"
        if self.until_steady and step.change:
            worst = max(step.change.values())
            return f"change {100 * worst:.2g} % (steady below {100 * step.steady_tolerance:.2g} %)"
        return ""

    def close(self, completed: bool = True) -> None:
        """The run has ended: a completed run's bar shows 100 % (settled or at its cap)."""
        if completed:
            self.fraction = 1.0
        if self.bar is not None:
            if completed:
                self.bar.set_postfix_str("", refresh=False)
                self.bar.update(1.0 - self.bar.n)
            self.bar.close()


def _clock(seconds: float) -> str:
    m, s = divmod(int(round(seconds)), 60)
    return f"{m // 60}:{m % 60:02d}:{s:02d}" if m >= 60 else f"{m:02d}:{s:02d}"
