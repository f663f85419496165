"""Progress lines: wall-clock stamps and the time-left estimate of loops of known length."""
import re
from types import SimpleNamespace

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


def test_steps_of_unequal_size_scale_the_time_left_by_the_work_still_to_do(monkeypatch):
    clock = iter([0.0, 10.0, 40.0, 50.0])  # t0, then the end of each step (and the last t0)
    monkeypatch.setattr(progress.time, "monotonic", lambda: next(clock))
    work = progress.Work([1.0, 2.0, 1.0])  # e.g. solves weighted by their expected cost
    assert work.done() == "(1/3 done, about 30 s left)"   # 1 unit in 10 s, 3 units to go
    assert work.done() == "(2/3 done, about 13 s left)"   # 3 units in 40 s, 1 unit to go
    assert progress.Work([5.0]).done() == "(1/1 done)"    # nothing left: no estimate


def test_edge_levels_report_the_time_left_weighted_by_their_size(monkeypatch):
    from jointid.identification import polish

    lines = []
    monkeypatch.setattr(polish, "solve_point", lambda spec, model, theta, n_modes, describe, **kw: (None, None, None, None))
    monkeypatch.setattr(polish, "edge_limit", lambda solves, ratio=None: solves)

    class Model:
        def __init__(self, n):
            self.n_dofs, self.stiffness = n, {}

    spec = SimpleNamespace(joints=None, mesh_file=None, solver=SimpleNamespace(n_modes=4),
                           mesh=SimpleNamespace(edge_ratio=None))
    monkeypatch.setattr(polish, "joint_terms", lambda joints, mesh_file: {})
    polish.edge_limit_at(spec, [Model(100), Model(200), Model(300)], {}, log=lines.append, base=("f", "s"),
                         sizes=[100, 200, 300])
    assert [re.sub(r"about \d+ s", "about N s", ln) for ln in lines] == [
        "edge level +1: 200 DOFs solved (1/2 done, about N s left)", "edge level +2: 300 DOFs solved (2/2 done)"]
