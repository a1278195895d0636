import json
import warnings

import numpy as np
import pytest

from qsid_core import LTISystem, SystemDefinitionError, UncontrollableWarning, get_system, load_system
from qsid_core.plant.systems import boeing747, dc_motor, dc_motor_physical, system_from_dict
from qsid_core.validate import parse_matrix


def test_presets_have_letter_shapes_and_defaults():
    m = dc_motor()
    assert (m.n, m.m) == (3, 2)
    np.testing.assert_allclose(m.x0, [1, 0, 0])
    np.testing.assert_allclose(np.diag(m.Q), [1, 0.1, 0.1])
    np.testing.assert_allclose(m.R, np.eye(2))
    b = boeing747()
    assert (b.n, b.m) == (4, 2)
    np.testing.assert_allclose(b.x0, [1, 1, 0, 0])
    np.testing.assert_allclose(np.diag(b.Q), [1, 0.1, 0.1, 0.1])
    assert m.controllable and b.controllable


def test_physical_motor_reproduces_printed_matrices_at_1s():
    phys, printed = dc_motor_physical(1.0), dc_motor()
    np.testing.assert_allclose(phys.A, printed.A, atol=1e-3)  # the letter truncates to 3 decimals
    np.testing.assert_allclose(phys.B, printed.B, atol=1e-3)  # the letter truncates to 3 decimals
    # a different sample time gives a different model
    assert np.abs(dc_motor_physical(0.01).A - printed.A).max() > 0.5


def test_matrices_are_read_only():
    m = dc_motor()
    with pytest.raises(ValueError):
        m.A[0, 0] = 3.0


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(A=[[1, 0], [0, 1]], B=[[1], [0], [0]]), "B must have shape"),
        (dict(A=[[1, 0, 0], [0, 1, 0]], B=[[1], [0]]), "square"),
        (dict(A=[[1, np.nan], [0, 1]], B=[[1], [0]]), "finite"),
        (dict(A=[[1, 0], [0, 1]], B=[[1], [1]], x0=[1, 2, 3]), "x0"),
        (dict(A=[[1, 0], [0, 1]], B=[[1], [1]], Q=[[1, 2], [0, 1]]), "symmetric"),
        (dict(A=[[1, 0], [0, 1]], B=[[1], [1]], R=[[-1]]), "positive definite"),
        (dict(A=[[1, 0], [0, 1]], B=[[1], [1]], Q=[-1, 1]), "semidefinite"),
        (dict(A="abc", B=[[1]]), "matrix of numbers"),
    ],
)
def test_bad_system_definitions_raise_clear_errors(kwargs, match):
    with pytest.raises(SystemDefinitionError, match=match):
        LTISystem("bad", **kwargs)


def test_uncontrollable_system_warns_not_crashes():
    with pytest.warns(UncontrollableWarning, match="not controllable"):
        s = LTISystem("unc", [[0.5, 0], [0, 0.5]], [[1], [0]])
    assert not s.controllable and s.controllability_rank == 1


def test_toml_and_json_files(tmp_path):
    t = tmp_path / "plant.toml"
    t.write_text("A = [[0.9, 0.1], [0.0, 0.8]]\nB = [[0.0], [1.0]]\nx0 = [1.0, -1.0]\nQ = [1.0, 2.0]\nR = [[0.5]]\n")
    s = load_system(t)
    assert s.name == "plant" and s.n == 2 and s.m == 1
    np.testing.assert_allclose(np.diag(s.Q), [1, 2])
    j = tmp_path / "plant.json"
    j.write_text(json.dumps(s.to_dict()))
    s2 = get_system(str(j))
    np.testing.assert_allclose(s2.A, s.A)
    np.testing.assert_allclose(s2.R, s.R)


@pytest.mark.parametrize(
    "name, text, match",
    [
        ("bad.toml", "A = [[1, 0], [0", "cannot parse"),
        ("bad.json", "{not json", "cannot parse"),
        ("nob.toml", "A = [[1.0]]", "missing 'B'"),
        ("extra.toml", "A = [[1.0]]\nB = [[1.0]]\nC = [[1.0]]", "unknown key"),
        ("plant.yaml", "A: 1", "must end in .toml or .json"),
    ],
)
def test_bad_system_files(tmp_path, name, text, match):
    p = tmp_path / name
    p.write_text(text)
    with pytest.raises(SystemDefinitionError, match=match):
        load_system(p)


def test_unknown_system_name_lists_presets():
    with pytest.raises(SystemDefinitionError, match="dc-motor"):
        get_system("no-such-plant")
    with pytest.raises(SystemDefinitionError, match="does not exist"):
        get_system("/nonexistent/x.toml")


def test_parse_matrix_forms_and_errors():
    np.testing.assert_allclose(parse_matrix("1 2; 3 4"), [[1, 2], [3, 4]])
    np.testing.assert_allclose(parse_matrix("1, 2\n3, 4"), [[1, 2], [3, 4]])
    np.testing.assert_allclose(parse_matrix("[[1, 2], [3, 4]]"), [[1, 2], [3, 4]])
    with pytest.raises(SystemDefinitionError, match="different lengths"):
        parse_matrix("1 2; 3")
    with pytest.raises(SystemDefinitionError, match="row 2"):
        parse_matrix("1 2; 3 x")
    with pytest.raises(SystemDefinitionError, match="empty"):
        parse_matrix("  ")


def test_system_from_dict_requires_mapping():
    with pytest.raises(SystemDefinitionError):
        system_from_dict([1, 2])  # type: ignore[arg-type]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        system_from_dict({"A": [[0.5]], "B": [[1.0]]})


def test_new_presets_sources_and_data_rate():
    import numpy as np

    from qsid_core.control import data_rate_bits
    from qsid_core.plant.systems import PRESETS, dc_motor_physical, get_system

    assert {"dc-motor-50ms", "inverted-pendulum", "mass-spring-damper"} <= set(PRESETS)
    fast = get_system("dc-motor-50ms")
    np.testing.assert_allclose(fast.A, dc_motor_physical(0.05).A)
    assert fast.dt == 0.05
    pend = get_system("inverted-pendulum")
    lam = np.abs(np.linalg.eigvals(pend.A))
    assert lam.max() == pytest.approx(np.exp(np.sqrt(2.1 * 9.81 / 1.0) * 0.05), rel=1e-9)  # (M+m)g/(Ml) = 20.6
    assert data_rate_bits(pend.A) == pytest.approx(np.log2(lam.max()), rel=1e-6) and 0.3 < data_rate_bits(pend.A) < 0.4
    msd = get_system("mass-spring-damper")
    assert msd.n == 2 and msd.m == 1 and np.abs(np.linalg.eigvals(msd.A)).max() < 1
    assert data_rate_bits(msd.A) == 0.0 and data_rate_bits(get_system("dc-motor").A) == pytest.approx(0.0, abs=1e-12)
