"""Every claim of the control lessons (how many bits, tracking, quantized feedback), on the dashboard's numbers."""

from __future__ import annotations

import numpy as np
import pytest

from app.lessons.table import get_lesson, lesson_values
from app.settings.config import sweep_config
from app.settings.values import resolve_system
from qsid_core import Experiment
from qsid_core.studies.bits import bits_needed

pytestmark = pytest.mark.slow


def _config(name: str, **over):
    v = lesson_values(name).replace(**over)
    return sweep_config(v, resolve_system(v).system)


def test_bits_needed_lesson():
    les = get_lesson("bits-needed")
    assert les.plot == "bits" and "b_observed" in les.text and "for the model the title names" in les.text
    cfg = _config("bits-needed")
    ans = bits_needed(cfg)
    assert (ans.b_observed, ans.b_robust, ans.b_letter) == (4, 5, 9)  # the title's numbers (not the text's)
    assert "(at b = 5: every loop's own model)" in ans.sentence  # the title names the certificate's model
    assert "at least 95 % of the loops, with a cost within 1 %" in ans.sentence  # as the text words them
    lp = ans.result.loops[2]
    oc = lp.outcome_counts()
    assert oc["converged"] <= 0.2 * len(lp.outcome) and not any(lp.failure)  # most never settle, none fails
    stuck = [r for r, o in enumerate(lp.outcome) if o != "converged"]
    assert np.all(lp.spectral_radius[stuck] > 1)


def test_tracking_lesson():
    les = get_lesson("tracking")
    assert les.plot == "residual" and "sine:u:1:40" in les.text
    ex = Experiment(_config("tracking"))
    true = float(ex.true_model_loop().tracking_error[0])
    err = {b: float(np.nanmean(ex.closed_loops(b, "ls").tracking_error)) for b in (2, 4, 6, 8, 12)}
    assert err[2] > 2 * true
    assert all(abs(err[b] / true - 1) < 0.05 for b in (4, 6, 8, 12)), (err, true)


def test_feedback_lesson():
    les = get_lesson("feedback")
    assert les.plot == "residual" and "about 0.8" in les.text
    ex = Experiment(_config("feedback"))
    true = float(ex.true_model_loop().steady_state_error[0])
    err = {b: float(np.nanmean(ex.closed_loops(b, "ls").steady_state_error)) for b in (8, 12, 16)}
    assert 0.6 < true < 1.0
    assert all(abs(e / true - 1) < 0.01 for e in err.values()), (err, true)
    ex8 = Experiment(_config("feedback", feedback_bits=8))
    e8 = float(np.nanmean(ex8.closed_loops(12, "ls").steady_state_error))
    assert e8 > 0 and err[12] > 4 * e8
