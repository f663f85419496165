"""jointid.isolate: a step computed in a child process gives the caller's answer, its errors, and says when
the child was killed."""

from __future__ import annotations

import math
import os
import pickle
from types import MappingProxyType

import numpy as np
import pytest

from jointid import isolate
from jointid.config.load import load_config
from jointid.config.typed_mesh import read_only
from jointid.errors import ConfigError, ModelError


def test_the_childs_answer_is_the_callers():
    assert isolate.call(math.factorial, 20) == 2432902008176640000  # exact: 20!
    a = np.random.default_rng(3).standard_normal((40, 40))
    a = a + a.T
    got = isolate.call(np.linalg.eigvalsh, a)
    assert np.array_equal(got, np.linalg.eigvalsh(a))  # the same code on the same bits: the same bits
    assert isolate.call(np.full, 3, fill_value=2.5).tolist() == [2.5, 2.5, 2.5]  # keyword arguments pass too


def test_an_error_in_the_child_is_raised_in_the_caller():
    with pytest.raises(ValueError, match="math domain error"):
        isolate.call(math.sqrt, -1.0)
    with pytest.raises(ConfigError, match="x.yaml: file not found"):  # the project's errors keep their type
        isolate.call(load_config, "/nonexistent/x.yaml")


def test_a_child_killed_by_a_signal_is_one_clear_error():
    with pytest.raises(ModelError, match=r"the test step: its process was killed by signal 6"):
        isolate.call(os.abort, what="the test step")


def test_read_only_mappings_of_the_typed_config_pickle():
    m = read_only({"a": {"b": 1.0}})  # what the typed objects hold (pickled by a rule of jointid.config.typed_mesh)
    back = pickle.loads(pickle.dumps(m))
    assert isinstance(back, MappingProxyType) and isinstance(back["a"], MappingProxyType)
    assert back["a"]["b"] == 1.0


def test_a_worker_started_ahead_makes_its_call_and_ends_cleanly():
    with isolate.Worker("fractions", what="the test step") as worker:  # imports fractions while we go on
        worker.submit(math.comb, 30, 15)
        assert worker.result() == 155117520  # C(30, 15)
    with isolate.Worker("fractions") as idle:  # never asked: ended on close, without an answer or an error
        pass
    assert idle._proc.returncode == 0


def test_the_page_figures_drawn_by_a_worker_are_the_pages_own():
    import pandas as pd

    from jointid.reporting.diagnosis_figures import PRELOAD, FigureData, figures

    paired = pd.DataFrame({"status": ["paired"] * 3, "state": ["s1", "s1", "s2"], "freq_meas_Hz": [100.0, 200.0, 150.0],
                           "error_pct": [1.0, -2.0, 0.5]})
    data = FigureData(
        ladder=pd.DataFrame({"state": ["s1", "s1"], "variant": ["baseline", "+a"], "max_abs_error_pct": [5.0, 1.0],
                             "rms_error_pct": [3.0, 0.5]}),
        compare=paired, current=paired,
        ranking=pd.DataFrame({"effect": ["a", "b"], "explained_fraction": [0.8, 0.1], "explains": [True, False]}),
        point_residuals=pd.DataFrame({"point": ["T01", "T02"], "rms_residual": [0.1, 0.2]}),
        mac={"s1": np.eye(2)})
    with isolate.Worker(*PRELOAD, env={"MPLBACKEND": "Agg"}) as worker:
        worker.submit(figures, data)
        drawn = worker.result()
    assert drawn == figures(data) and set(drawn) == {"ladder", "errors", "ranking", "points", "mac_s1"}


def test_a_figure_worker_that_fails_leaves_the_figures_to_the_page():
    from jointid.stages.diagnosis import _figures_made

    class Dead:  # a worker whose process died (e.g. killed): its result says so
        asked = True

        def result(self):
            raise ModelError("the diagnosis page's figures: its process was killed by signal 9 (out of memory?)")

    said = []
    assert _figures_made(Dead(), said.append) is None  # html_page then draws them in the job's own process
    with isolate.Worker() as idle:  # handed nothing (the diagnosis stopped before its tables): not waited for
        assert not idle.asked and _figures_made(idle, said.append) is None
    assert said and "drawn in this process" in said[0] and "signal 9" in said[0]
    assert _figures_made(None, said.append) is None and len(said) == 1  # no worker: nothing to say

    class Broken:  # the figures themselves fail: the error is the job's, as when drawn in its own process
        asked = True

        def result(self):
            raise ValueError("bad figure data")

    with pytest.raises(ValueError, match="bad figure data"):
        _figures_made(Broken(), said.append)
