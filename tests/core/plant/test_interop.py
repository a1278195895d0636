"""python-control interop (qsid_core/interop.py): StateSpace in, identified models out."""

import numpy as np
import pytest

control = pytest.importorskip("control")

from qsid_core import SweepConfig, dc_motor, dc_motor_physical, run_sweep  # noqa: E402
from qsid_core.errors import SystemDefinitionError  # noqa: E402
from qsid_core.plant.interop import (  # noqa: E402
    identified_statespaces,
    model_to_statespace,
    system_from_statespace,
    system_to_statespace,
)


def test_discrete_round_trip_keeps_matrices_dt_and_names():
    true = dc_motor()
    ss = system_to_statespace(true)
    assert ss.dt == true.dt and ss.isdtime(strict=True)
    np.testing.assert_array_equal(ss.C, np.eye(3))
    np.testing.assert_array_equal(ss.D, np.zeros((3, 2)))
    back = system_from_statespace(ss, x0=true.x0, Q=true.Q, R=true.R)
    np.testing.assert_array_equal(back.A, true.A)
    np.testing.assert_array_equal(back.B, true.B)
    assert back.dt == true.dt and back.name == "dc-motor"
    assert back.state_names == true.state_names and back.input_names == true.input_names


def test_discrete_with_other_dt_and_default_labels():
    ss = control.ss([[0.5, 0.1], [0.0, 0.9]], [[0.0], [1.0]], np.eye(2), [[0.0], [0.0]], 0.02)
    s = system_from_statespace(ss)
    assert s.dt == 0.02 and s.name == "statespace"
    assert s.state_names == ("x1", "x2") and s.input_names == ("u1",)  # python-control's x[0] -> qsid defaults
    with pytest.raises(SystemDefinitionError, match="dt=0.02"):
        system_from_statespace(ss, dt=0.1)
    unspecified = control.ss(ss.A, ss.B, ss.C, ss.D, True)
    assert system_from_statespace(unspecified).dt == 1.0
    assert system_from_statespace(unspecified, dt=0.5).dt == 0.5


def test_continuous_via_c2d_matches_the_physical_motor():
    J, c, K, Ke, r, L = 0.01, 0.1, 0.01, 0.01, 1.0, 0.5
    Ac = np.array([[0.0, 1.0, 0.0], [0.0, -c / J, K / J], [0.0, -Ke / L, -r / L]])
    Bc = np.array([[0.0, 0.0], [0.0, 1.0 / J], [1.0 / L, 0.0]])
    cont = control.ss(Ac, Bc, np.eye(3), np.zeros((3, 2)))
    with pytest.raises(SystemDefinitionError, match="continuous-time"):
        system_from_statespace(cont)
    s = system_from_statespace(cont, dt=1.0, name="motor")
    ref = dc_motor_physical(1.0)
    np.testing.assert_allclose(s.A, ref.A, rtol=0, atol=1e-12)
    np.testing.assert_allclose(s.B, ref.B, rtol=0, atol=1e-12)
    assert s.dt == 1.0 and s.name == "motor"
    np.testing.assert_allclose(s.A, dc_motor().A, atol=1e-3)  # the letter's printed (truncated) matrices


def test_output_rule_full_state_or_ignore():
    A, B = np.diag([0.5, 0.8]), np.array([[1.0], [0.5]])
    partial = control.ss(A, B, [[1.0, 0.0]], [[0.0]], 1.0)
    with pytest.raises(SystemDefinitionError, match="full-state systems: C must be the 2 x 2 identity") as ei:
        system_from_statespace(partial)
    assert "\n" not in str(ei.value)
    feedthrough = control.ss(A, B, np.eye(2), [[0.0], [0.3]], 1.0)
    with pytest.raises(SystemDefinitionError, match="not I|D zero"):
        system_from_statespace(feedthrough)
    s = system_from_statespace(partial, outputs="ignore")
    np.testing.assert_array_equal(s.A, A)
    np.testing.assert_array_equal(s.B, B)


def test_refuses_what_is_not_a_statespace_or_has_no_timebase():
    with pytest.raises(SystemDefinitionError, match="control.StateSpace"):
        system_from_statespace(control.tf([1], [1, 1]))
    either = control.ss([[0.5]], [[1.0]], [[1.0]], [[0.0]], None)
    with pytest.raises(SystemDefinitionError, match="unspecified timebase"):
        system_from_statespace(either)
    with pytest.raises(SystemDefinitionError, match="positive"):
        model_to_statespace(np.eye(2), np.ones((2, 1)), dt=0)


def test_identified_models_come_back_as_statespace_and_run_in_python_control():
    ss_true = control.ss(
        [[0.9, 0.1], [0.0, 0.7]],
        [[0.0], [1.0]],
        np.eye(2),
        [[0.0], [0.0]],
        0.1,
        states=["pos", "vel"],
        inputs=["force"],
        name="cart",
    )
    true = system_from_statespace(ss_true)
    res = run_sweep(SweepConfig(system=true, bits=(4, 12), realizations=3, trajectories=8, steps=200, mpc=None))
    for b in (4, 12):
        models = identified_statespaces(res.identification[b], true)
        assert len(models) == 3
        for r, m in enumerate(models):
            assert m.dt == 0.1 and m.state_labels == ["pos", "vel"] and m.input_labels == ["force"]
            np.testing.assert_array_equal(m.A, res.identification[b].A_hat[r])
            np.testing.assert_array_equal(m.B, res.identification[b].B_hat[r])
            back = system_from_statespace(m)  # and back into the engine
            np.testing.assert_array_equal(back.A, m.A)
    # finer quantization -> the identified poles approach the true ones (a python-control computation)
    err = {
        b: max(
            np.max(np.abs(np.sort(m.poles().real) - np.sort(ss_true.poles().real)))
            for m in identified_statespaces(res.identification[b], true)
        )
        for b in (4, 12)
    }
    assert err[12] < err[4]


def test_failed_identification_gives_none():
    true = dc_motor()
    res = run_sweep(SweepConfig(bits=(6,), realizations=2, trajectories=4, steps=60, mpc=None))
    ident = res.identification[6]
    ident.failed[1] = True
    out = identified_statespaces(ident, true)
    assert out[0] is not None and out[1] is None
