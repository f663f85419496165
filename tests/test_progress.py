"""Progress lines: wall-clock stamps and the time-left estimate of loops of known length."""
import re

from jointid import progress


def test_time_left_is_the_mean_step_time_times_the_steps_left(monkeypatch):
    clock = iter([100.0, 110.0, 130.0, 200.0, 210.0])  # t0, then the moments of each call
    monkeypatch.setattr(progress.time, "monotonic", lambda: next(clock))
    steps = progress.Steps(4)
    assert steps.next() == "(1/4)"                          # nothing finished: no estimate
    assert steps.next() == "(2/4, about 30 s left)"         # 1 step in 10 s, 3 to go
    assert steps.next() == "(3/4, about 30 s left)"         # 2 steps in 30 s, 2 to go
    done = progress.Steps(2)                                # t0 = 200
    assert done.done() == "(1/2 done, about 10 s left)"     # 1 step in 10 s, 1 to go


def test_every_progress_line_carries_the_wall_clock():
    assert re.fullmatch(r"\[\d\d:\d\d:\d\d\] diagnosis: refitting", progress.stamp("diagnosis: refitting"))
