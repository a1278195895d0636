"""The real loop: disturbance on the true plant, quantized and noisy state feedback, the steady-state error."""

import json

import numpy as np
import pytest

from app.cli import main
from qsid_core.control.closed_loop import run_closed_loops
from qsid_core.control.loop_noise import loop_noise
from qsid_core.control.mpc import MPCConfig
from qsid_core.errors import ConfigError
from qsid_core.plant.systems import get_system
from qsid_core.studies.config import SweepConfig
from qsid_core.studies.experiment import Experiment

DATA = ["--realizations", "6", "--trajectories", "50", "--steps", "300", "-q", "--json"]


def _sweep(capsys, *args):
    assert main(["sweep", *DATA, *args]) == 0
    return json.loads(capsys.readouterr().out)


def test_feedback_bits_set_a_floor_that_falls_with_the_word_length(capsys):
    """Training b = 12: the residual is nonzero and at least 4x smaller with 8 feedback bits than with 4."""
    e4 = _sweep(capsys, "--bits", "12", "--feedback-bits", "4")
    e8 = _sweep(capsys, "--bits", "12", "--feedback-bits", "8")
    clean = _sweep(capsys, "--bits", "12")
    s4, s8 = (d["results"][0]["steady_state_error"]["mean"] for d in (e4, e8))
    s0 = clean["results"][0]["steady_state_error"]["mean"]
    assert s8 > 0 and s4 >= 4 * s8 and s8 > 10 * s0
    assert e8["steady_state_error_true_model"] > 10 * clean["steady_state_error_true_model"]
    assert e8["config"]["mpc"]["feedback_bits"] == 8 and e8["data_rate_bits"] == pytest.approx(0.0, abs=1e-9)


def test_disturbance_leaves_a_residual_for_every_model_and_the_true_model(capsys):
    d = _sweep(capsys, "--bits", "4,8", "--disturbance", "0.01")
    ex = Experiment(
        SweepConfig(bits=(4, 8), realizations=6, trajectories=50, steps=300, mpc=MPCConfig(disturbance=0.01))
    )
    for b in (4, 8):
        sse = ex.closed_loops(b).steady_state_error
        assert np.all(sse > 1e-4)
    assert d["steady_state_error_true_model"] > 1e-4
    assert all(r["closed_loop_outcomes"]["converged"] == 6 for r in d["results"])  # the law is still stable


def test_same_draws_for_every_loop_and_seeded():
    s = get_system("dc-motor")
    cfg = MPCConfig(disturbance=0.05, loop_seed=7)
    a, b = loop_noise(cfg, 3, 50), loop_noise(cfg, 3, 50)
    assert np.array_equal(a.w, b.w) and a.w.std() == pytest.approx(0.05, rel=0.3)
    assert not np.array_equal(a.w, loop_noise(MPCConfig(disturbance=0.05, loop_seed=8), 3, 50).w)
    u = loop_noise(MPCConfig(disturbance=0.05, disturbance_kind="uniform"), 3, 2000)
    assert np.abs(u.w).max() <= 0.05 * np.sqrt(3) and u.w.std() == pytest.approx(0.05, rel=0.1)
    assert loop_noise(MPCConfig(), 3, 50) is None
    # two copies of the true model in one run see the same disturbance: identical loops
    lp = run_closed_loops([(s.A, s.B), (s.A, s.B)], s.A, s.B, cfg, s)
    assert np.array_equal(lp.states[0], lp.states[1]) and lp.steady_state_error[0] > 0


def test_quantized_measurement_is_the_letters_quantizer():
    from qsid_core.quantization.quantize import quantize

    cfg = MPCConfig(feedback_bits=5)
    lo, hi = np.array([-2.0, -1.0]), np.array([2.0, 3.0])
    nz = loop_noise(cfg, 2, 10, (lo, hi, True))
    x = np.array([[0.3, -0.7], [1.9, 2.5]])
    want = quantize(x, lo, hi, 5, guard=True, unit_dither=np.broadcast_to(nz.dither[3], x.shape)).values
    np.testing.assert_allclose(nz.measure(x, 3), want, rtol=0, atol=1e-12)


@pytest.mark.parametrize(
    "kw, field",
    [
        (dict(disturbance=-0.1), "disturbance"),
        (dict(feedback_bits=0), "feedback bits"),
        (dict(feedback_noise=float("nan")), "feedback noise"),
        (dict(disturbance_kind="cauchy"), "disturbance kind"),
        (dict(loop_seed=-1), "loop seed"),
    ],
)
def test_bad_real_loop_settings(kw, field):
    with pytest.raises(ConfigError, match=field):
        MPCConfig(**kw)


@pytest.mark.parametrize(
    "args, message",
    [
        (["--feedback-bits", "0"], "argument --feedback-bits: must be a word length 1..32 or 'none'"),
        (["--disturbance", "0.1:cauchy"], "argument --disturbance: must be SIGMA"),
        (["--disturbance=-1"], "argument --disturbance: must be >= 0"),
        (["--feedback-noise", "x"], "argument --feedback-noise"),
    ],
)
def test_cli_real_loop_bad_input_is_one_line(capsys, args, message):
    assert main(["sweep", *DATA, *args]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err


def test_table_names_the_causes_and_the_data_rate_floor(capsys):
    assert (
        main(
            [
                "sweep",
                "--bits",
                "8",
                "--realizations",
                "3",
                "--trajectories",
                "20",
                "--steps",
                "100",
                "-q",
                "--feedback-bits",
                "6",
                "--system",
                "boeing747",
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "steady err" in out and "feedback quantized to 6 bits per state" in out
    assert "delta covers the model error only" in out and "data-rate floor of this plant: 0 bits" in out
