"""Progress lines of long stages: a wall-clock stamp on every line, and for loops of known length
the step and an estimate of the time left (from the mean time of the steps done so far)."""

from __future__ import annotations

import time


def stamp(msg: str) -> str:
    """``msg`` prefixed with the wall-clock time ``[HH:MM:SS]``."""
    return f"[{time.strftime('%H:%M:%S')}] {msg}"


class Steps:
    """Counter of a loop of ``n`` steps: :meth:`next` gives ``"(k/n)"`` before step k, with ``about
    X s left`` once a step has finished; :meth:`done` gives ``"(k/n done, about X s left)"`` after it."""

    def __init__(self, n: int):
        self.n, self.k, self.t0 = int(n), 0, time.monotonic()

    def next(self) -> str:
        self.k += 1
        if self.k == 1 or self.n <= 1:
            return f"({self.k}/{self.n})"
        per = (time.monotonic() - self.t0) / (self.k - 1)
        return f"({self.k}/{self.n}, about {per * (self.n - self.k + 1):.0f} s left)"

    def done(self) -> str:
        self.k += 1
        if self.k >= self.n:
            return f"({self.k}/{self.n} done)"
        per = (time.monotonic() - self.t0) / self.k
        return f"({self.k}/{self.n} done, about {per * (self.n - self.k):.0f} s left)"


class Work:
    """Counter of a loop whose steps differ in size: ``weights`` (one per step, e.g. the expected cost
    of each solve).  :meth:`done` after step k gives ``"(k/n done, about X s left)"``, the time left
    being the time so far scaled by the weight still to do over the weight done."""

    def __init__(self, weights):
        self.w = [float(x) for x in weights]
        self.k, self.t0 = 0, time.monotonic()

    def done(self) -> str:
        self.k += 1
        n = len(self.w)
        if self.k >= n:
            return f"({self.k}/{n} done)"
        did, left = sum(self.w[: self.k]), sum(self.w[self.k:])
        if did <= 0:
            return f"({self.k}/{n} done)"
        return f"({self.k}/{n} done, about {(time.monotonic() - self.t0) * left / did:.0f} s left)"

