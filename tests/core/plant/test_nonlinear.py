"""Nonlinear plants: RK4 sampling, presets, training runs, custom vector fields and their errors."""

from __future__ import annotations

import sys
import types

import numpy as np
import pytest

from qsid_core.errors import ConfigError, QsidError, SystemDefinitionError
from qsid_core.plant import (
    NONLINEAR_PRESETS,
    NonlinearSystem,
    get_nonlinear,
    nonlinear_from_dict,
    rk4_step,
    simulate_nonlinear,
)


def test_rk4_step_matches_a_hand_written_step_of_van_der_pol():
    s = get_nonlinear("van-der-pol")
    x, u, h = np.array([[1.2, -0.7]]), np.array([[0.3]]), 0.05

    def f(v):
        return np.array([v[1], (1 - v[0] ** 2) * v[1] - v[0] + 0.3])

    v = x[0]
    k1 = f(v)
    k2 = f(v + h / 2 * k1)
    k3 = f(v + h / 2 * k2)
    k4 = f(v + h * k3)
    want = v + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    np.testing.assert_allclose(s.step(x, u)[0], want, rtol=1e-14)


def test_rk4_is_fourth_order_on_a_linear_field():
    # xdot = -x: one RK4 step is the Taylor polynomial of exp(-h) to fourth order
    x = np.ones((1, 1))
    got = rk4_step(lambda x, u: -x, x, np.zeros((1, 1)), 0.1)[0, 0]
    assert got == pytest.approx(1 - 0.1 + 0.01 / 2 - 0.001 / 6 + 0.0001 / 24, rel=1e-14)


@pytest.mark.parametrize("name", sorted(NONLINEAR_PRESETS))
def test_presets_give_training_runs_with_the_documented_draws(name):
    s = get_nonlinear(name)
    d = simulate_nonlinear(s, 30, 20, seed=3)
    assert d.states.shape == (30, 21, 2) and d.inputs.shape == (30, 20, 1)
    assert np.all(np.abs(d.inputs) <= 1) and np.all(np.abs(d.states[:, 0]) <= s.amplitude)
    assert d.left_box == () and d.report == ""
    np.testing.assert_allclose(d.states[:, 1], s.step(d.states[:, 0], d.inputs[:, 0]))


def test_runs_leaving_the_sane_box_are_reported_not_silently_dropped():
    s = NonlinearSystem("blowup", lambda x, u: x * x, 1, 1, amplitude=2.0, box=10.0)  # x' = x^2 blows up for x > 0
    d = simulate_nonlinear(s, 20, 40, seed=0)
    assert 0 < len(d.left_box) < 20 and d.trajectories == 20 - len(d.left_box)
    assert d.report.startswith(f"{len(d.left_box)} of 20 runs left the sane box")
    assert np.all(np.abs(d.states) <= 10)


def test_a_vector_field_that_raises_or_returns_nan_is_one_error_naming_it():
    def bad(x, u):
        raise RuntimeError("boom")

    with pytest.raises(SystemDefinitionError, match="vector field of 'mine' raised RuntimeError: boom"):
        simulate_nonlinear(NonlinearSystem("mine", bad, 2, 1), 2, 2)
    with pytest.raises(SystemDefinitionError, match="vector field of 'nan' returned NaN"):
        simulate_nonlinear(NonlinearSystem("nan", lambda x, u: np.sqrt(x - 10), 2, 1), 2, 2)
    with pytest.raises(SystemDefinitionError, match="returned shape"):
        simulate_nonlinear(NonlinearSystem("shape", lambda x, u: x[:, :1], 2, 1), 2, 2)


def test_unknown_preset_and_bad_sizes_are_config_errors():
    with pytest.raises(ConfigError, match="unknown nonlinear system"):
        get_nonlinear("lorenz")
    with pytest.raises(QsidError, match="trajectories"):
        simulate_nonlinear(get_nonlinear("duffing"), 0, 10)


def test_a_plant_file_names_its_vector_field_as_module_function(monkeypatch):
    mod = types.ModuleType("qsid_test_field")
    mod.field = lambda x, u: -x + u  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "qsid_test_field", mod)
    s = nonlinear_from_dict({"vector_field": "qsid_test_field:field", "n": 1, "m": 1, "dt": 0.1})
    assert s.dt == 0.1 and s.step(np.zeros((1, 1)), np.ones((1, 1)))[0, 0] == pytest.approx(1 - np.exp(-0.1), 1e-6)
    with pytest.raises(SystemDefinitionError, match="cannot be loaded"):
        nonlinear_from_dict({"vector_field": "qsid_test_field:nothing", "n": 1, "m": 1})
    with pytest.raises(SystemDefinitionError, match="module:function"):
        nonlinear_from_dict({"vector_field": "nocolon", "n": 1, "m": 1})


SPRING = """import numpy as np


def field(x, u):
    return np.stack([x[:, 1], u[:, 0] - 0.5 * x[:, 1] - x[:, 0] - x[:, 0] ** 3], axis=1)
"""


def _plant_beside(folder, module: str, ref: str | None = None):
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{module}.py").write_text(SPRING)
    p = folder / "spring.toml"
    p.write_text(f'vector_field = "{ref or module}:field"\nn = 2\nm = 1\nx0 = [1.0, 0.0]\n')
    return p


def test_a_plant_files_module_beside_it_loads_without_pythonpath_and_pickles_by_folder(tmp_path):
    """The folder is searched for that import only (sys.path as before), and a worker process (a fresh
    interpreter without the folder on its path) unpickles the field from the same folder."""
    import pickle
    import subprocess

    from qsid_core.plant import load_nonlinear
    from qsid_core.plant.field_import import FileField

    p = _plant_beside(tmp_path / "plants", "qsid_beside_spring")
    before = list(sys.path)
    s = load_nonlinear(p)
    assert sys.path == before and isinstance(s.vector_field, FileField)
    x, u = np.array([[1.0, 2.0]]), np.array([[0.5]])
    np.testing.assert_allclose(s.xdot(x, u), [[2.0, 0.5 - 1.0 - 1.0 - 1.0]])
    blob = pickle.dumps(s)
    code = (
        "import pickle, sys, numpy as np; s = pickle.loads(sys.stdin.buffer.read()); "
        "print(s.xdot(np.array([[1.0, 2.0]]), np.array([[0.5]])).tolist())"
    )
    out = subprocess.run([sys.executable, "-c", code], input=blob, capture_output=True, timeout=300, cwd=tmp_path)
    assert out.returncode == 0, out.stderr.decode()
    assert out.stdout.decode().strip() == "[[2.0, -2.5]]"


def test_a_module_beside_the_plant_never_hides_an_installed_one(tmp_path):
    """A file beside the plant named as a module found elsewhere first (here the standard library's json) is
    not imported: one line says which module hides it."""
    from qsid_core.plant import load_nonlinear

    p = _plant_beside(tmp_path, "json")
    with pytest.raises(SystemDefinitionError, match="module 'json' beside the plant file is hidden by another"):
        load_nonlinear(p)
    q = tmp_path / "elsewhere.toml"  # a module neither beside the file nor installed: as before
    q.write_text('vector_field = "qsid_no_such_module:field"\nn = 2\nm = 1\n')
    with pytest.raises(SystemDefinitionError, match="cannot be loaded: ModuleNotFoundError"):
        load_nonlinear(q)
