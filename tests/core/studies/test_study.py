"""The engine's study: one front for both plant kinds, the current b first, cancellable, the same numbers as the
whole sweep, and sharing a cache."""

from __future__ import annotations

import numpy as np
import pytest

from qsid_core import CancelToken, Study, SweepConfig
from qsid_core.errors import ConfigError
from qsid_core.studies import KoopmanConfig, LinearAtBits, NonlinearAtBits, task_count

LINEAR = SweepConfig(system="dc-motor", bits=(3, 6, 9, 12), realizations=3, trajectories=20, steps=150)
NONLINEAR = KoopmanConfig(system="van-der-pol", bits=(3, 5, 7), trajectories=20, steps=60, realizations=2)


def test_a_linear_study_yields_the_current_b_first_then_the_rest_with_the_whole_sweeps_numbers():
    study = Study(LINEAR, estimators=("ls", "bcls"))
    frames = list(study.frames(bits=9, min_interval=0.0))
    first, last = frames[0], frames[-1]
    assert study.kind == "linear" and isinstance(first.at_bits, LinearAtBits)
    assert (
        first.stage == "current"
        and first.done == 1
        and {e: sorted(r) for e, r in first.rows.items()}
        == {
            "ls": [9],
            "bcls": [9],
        }
    )
    assert last.complete and sorted(last.rows["ls"]) == [3, 6, 9, 12]
    assert [f.done for f in frames] == sorted(f.done for f in frames)  # never backwards
    assert set(first.at_bits.loops) == {"ls", "bcls"} and first.at_bits.true_loop is not None
    swept = Study(LINEAR).run()  # the whole sweep, a study of its own (no shared cache)
    for b in LINEAR.bits:
        assert last.rows["ls"][b]["err_A"]["mean"] == pytest.approx(float(np.mean(swept.identification[b].err_A)))


def test_a_nonlinear_study_is_the_same_front_with_models_before_loops():
    study = Study(NONLINEAR)
    frames = list(study.frames(bits=5, min_interval=0.0))
    assert study.kind == "nonlinear" and isinstance(frames[0].at_bits, NonlinearAtBits)
    assert [f.stage for f in frames[:2]] == ["current", "models"]
    assert sorted(frames[0].rows["ls"]) == [5] and frames[0].rows["ls"][5]["closed_loop_outcomes"] is not None
    assert frames[1].rows["ls"][3]["closed_loop_outcomes"] is None  # models known, loops still to run
    assert frames[-1].complete and all(r["closed_loop_outcomes"] is not None for r in frames[-1].rows["ls"].values())
    swept = Study(NONLINEAR).run()
    by_b = {r["bits"]: r for r in swept.rows}
    for b in NONLINEAR.bits:
        assert frames[-1].rows["ls"][b]["err_G"]["mean"] == pytest.approx(by_b[b]["err_G"]["mean"])


def test_a_cancelled_study_stops_and_a_check_callable_cancels_too():
    token = CancelToken()
    frames = Study(LINEAR).frames(bits=3, cancel=token, min_interval=0.0, chunk=1)
    first = next(frames)
    token.cancel()
    rest = list(frames)
    assert first.stage == "current" and token.cancelled and not any(f.complete for f in rest)
    asked = []
    stop = CancelToken(lambda: bool(asked.append(1)) or len(asked) > 1)
    frames = list(Study(NONLINEAR).frames(bits=3, cancel=stop, min_interval=0.0))
    assert [f.stage for f in frames] == ["current"] and stop.cancelled


def test_two_studies_on_one_cache_share_every_stage():
    cache: dict = {}
    list(Study(LINEAR, cache=cache).frames(bits=6))
    filled = len(cache)
    frames = list(Study(LINEAR, cache=cache).frames(bits=12))  # another current b: nothing new to compute
    assert filled > 0 and len(cache) == filled and frames[-1].complete


def test_bad_input_names_the_field():
    with pytest.raises(ConfigError, match="config"):
        Study({"system": "dc-motor"})  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="bits"):
        next(Study(LINEAR).frames(bits=7))


def test_a_change_of_the_current_b_alone_starts_no_thread_and_submits_nothing(monkeypatch):
    import threading

    from qsid_core import InlineExecutor

    class Counting(InlineExecutor):
        submitted = 0

        def submit(self, fn, /, *args, **kwargs):
            Counting.submitted += 1
            return super().submit(fn, *args, **kwargs)

    cache: dict = {}
    list(Study(LINEAR, Counting(), cache, workers=2).frames(bits=6))
    cold = Counting.submitted
    started = []
    start = threading.Thread.start
    monkeypatch.setattr(threading.Thread, "start", lambda self: (started.append(self.name), start(self))[1])
    Counting.submitted = 0
    frames = list(Study(LINEAR, Counting(), cache, workers=2).frames(bits=12))
    assert cold > 0 and frames[-1].complete  # the first study did submit work
    assert started == [] and Counting.submitted == 0


def test_executor_tasks_last_a_fraction_of_a_second_and_use_every_worker():
    assert task_count(50 * 200, 20, 1, 2) == 2  # small data: one task per worker
    assert task_count(400 * 2000, 100, 1, 2) >= 8  # the panel's largest data: short tasks
    assert task_count(400 * 2000, 100, 15, 2) > task_count(400 * 2000, 100, 1, 2)  # a pass over more b
    assert task_count(10**8, 3, 15, 2) == 3  # never more tasks than realizations
    assert task_count(10, 1, 1, 4) == 1
    # as many tasks per worker: the paper scale's pass over 15 b (estimated 5 tasks) is split into 6
    assert task_count(200 * 1000 * 5 // 4, 50, 15, 2) == 6
    assert all(task_count(s, 50, b, 2) % 2 == 0 for s in (10**4, 10**5, 10**6) for b in (1, 8, 15))
