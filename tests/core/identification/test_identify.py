import numpy as np
import pytest

from qsid_core import Experiment, QuantizerSpec, SweepConfig, identify, prepare, relative_errors, simulate
from qsid_core.identification.identify import least_squares
from qsid_core.plant.systems import boeing747, dc_motor
from qsid_core.quantization.moments import Moments


@pytest.mark.parametrize("system", [dc_motor, boeing747])
def test_ls_recovers_true_matrices_from_unquantized_data(system):
    s = system()
    prep = prepare(simulate(s, 20, 300, seed=0), QuantizerSpec())
    ident = identify(prep.exact, "ls")
    assert np.abs(ident.A - s.A).max() < 1e-9
    assert np.abs(ident.B - s.B).max() < 1e-9
    # with eps = 0, BCLS is LS
    ib = identify(prep.exact, "bcls")
    assert ib.estimator == "bcls" and np.abs(ib.G - s.G).max() < 1e-9


def test_errors_shrink_as_bits_grow():
    ex = Experiment(SweepConfig(bits=(2, 6, 10, 14), realizations=4, trajectories=20, steps=300, mpc=None))
    errs = [ex.identification(b).err_A.mean() for b in (2, 6, 10, 14)]
    assert all(e1 > 3 * e2 for e1, e2 in zip(errs, errs[1:])), errs
    errs_b = [ex.identification(b).err_B.mean() for b in (2, 6, 10, 14)]
    assert all(e1 > 3 * e2 for e1, e2 in zip(errs_b, errs_b[1:])), errs_b


@pytest.mark.slow
def test_bias_compensation_ten_times_better_boeing_shared_b4():
    cfg = dict(system="boeing747", bits=(4,), realizations=5, quantizer=QuantizerSpec(range_mode="shared"), mpc=None)
    ex = Experiment(SweepConfig(**cfg))
    ls = ex.identification(4, "ls")
    bc = ex.identification(4, "bcls")
    assert not bc.fallback.any()
    assert bc.err_A.mean() * 10 <= ls.err_A.mean()
    assert bc.err_B.mean() * 10 <= ls.err_B.mean()


def test_bcls_falls_back_visibly_when_noise_swamps_signal():
    ex = Experiment(
        SweepConfig(
            system="boeing747",
            bits=(1,),
            realizations=3,
            trajectories=10,
            steps=100,
            quantizer=QuantizerSpec(range_mode="shared"),
            mpc=None,
        )
    )
    bc = ex.identification(1, "bcls")
    assert bc.fallback.all()
    assert bc.notes and "not positive definite" in bc.notes[0]
    np.testing.assert_allclose(bc.A_hat, ex.identification(1, "ls").A_hat)


def test_singular_data_and_bad_estimator():
    mo = Moments(PP=np.zeros((2, 2)), XP=np.zeros((1, 2)), T=10, eps=np.zeros(2))
    with pytest.raises(ValueError, match="not rich enough"):
        least_squares(mo.PP, mo.XP, 1)
    with pytest.raises(ValueError, match="estimator must be one of"):
        identify(mo, "ridge")


def test_relative_errors():
    A, B = np.eye(2), np.ones((2, 1))
    ea, eb = relative_errors(A * 1.1, B, A, B)
    assert ea == pytest.approx(0.1) and eb == 0.0
