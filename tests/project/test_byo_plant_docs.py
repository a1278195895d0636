"""The "bring your own plant" page: its plant files are its textbook sources' models, its outputs are
generated, and no plant in its examples gets a b_robust at which the loops are not all stable -- checked with
an independent computation (python-control's dlqr on each identified model, spectral radius on the true plant)."""

import json
import shlex
from pathlib import Path

import control
import numpy as np
import pytest

from app.cli import main
from qsid_core import Experiment, SweepConfig, load_system

ROOT = Path(__file__).resolve().parents[2]
PAGE = (ROOT / "docs" / "byo-plant.rst").read_text(encoding="utf-8")
DATA = ROOT / "docs" / "data"
BITS_LINES = [line.strip() for line in PAGE.splitlines() if line.strip().startswith("qsid bits ")]


def test_the_page_runs_its_commands_and_covers_the_five_plants():
    assert PAGE.count(".. qsid-run::") >= 6 and "code-block" not in PAGE
    for name in ("servo", "pitch", "pendcart", "chain", "bus"):
        assert f"--system {name}.toml" in PAGE and (DATA / f"{name}.toml").is_file()
    assert load_system(DATA / "chain.toml").n == 12


@pytest.mark.slow
@pytest.mark.parametrize("line", BITS_LINES, ids=[shlex.split(x)[3] for x in BITS_LINES])
def test_no_example_gets_a_b_robust_with_an_unstable_loop(line, tmp_path, capsys):
    argv = [str(DATA / a) if a.endswith(".toml") else a for a in shlex.split(line)[1:]]
    out = tmp_path / "bits.json"
    assert main([*argv, "--json", "--out", str(out)]) == 0
    capsys.readouterr()
    d = json.loads(out.read_text())
    if d["b_robust"] is None:
        assert all(not r["robust_certified"] for r in d["rows"][-1:])
        return
    cfg = SweepConfig.from_dict({k: v for k, v in d["settings"].items() if k not in ("target", "cost_gap")})
    ex = Experiment(cfg)
    s = ex.system
    for b in [r["bits"] for r in d["rows"] if r["bits"] >= d["b_robust"]]:
        ident = ex.identification(b)
        for A_h, B_h in zip(ident.A_hat, ident.B_hat):
            K = control.dlqr(A_h, B_h, s.Q, s.R)[0]  # the MPC's law with its DARE terminal weight
            assert np.abs(np.linalg.eigvals(s.A - s.B @ K)).max() < 1, (line, b)


def test_the_bus_at_one_newton_says_why_b_robust_is_not_given(capsys):
    line = next(x for x in BITS_LINES if "bus.toml" in x and "--input-amplitude" not in x)
    argv = [str(DATA / a) if a.endswith(".toml") else a for a in shlex.split(line)[1:]]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "b_robust = none" in text and "not certified: large-data hypothesis fails" in text


@pytest.mark.parametrize(
    "name, source",
    [
        ("servo", "servo"),
        ("pitch", "pitch"),
    ],
)
def test_plant_files_are_their_sources_discretized(name, source):
    """The servo and pitch files are the Michigan tutorials' continuous models under a zero-order hold."""
    if source == "servo":
        J, b, K, R, L = 3.2284e-6, 3.5077e-6, 0.0274, 4.0, 2.75e-6
        Ac = np.array([[0, 1, 0], [0, -b / J, K / J], [0, -K / L, -R / L]])
        Bc = np.array([[0], [0], [1 / L]])
        dt = 0.001
    else:
        Ac = np.array([[-0.313, 56.7, 0], [-0.0139, -0.426, 0], [0, 56.7, 0]])
        Bc = np.array([[0.232], [0.0203], [0]])
        dt = 0.01
    sysd = control.c2d(control.ss(Ac, Bc, np.eye(3), np.zeros((3, 1))), dt)
    s = load_system(DATA / f"{name}.toml")
    assert s.dt == dt
    np.testing.assert_allclose(s.A, sysd.A, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(s.B, sysd.B, rtol=1e-9, atol=1e-15)


def test_chain_file_is_six_unit_masses_between_walls():
    nm = 6
    Kk = 2 * np.eye(nm) - np.eye(nm, k=1) - np.eye(nm, k=-1)
    Ac = np.block([[np.zeros((nm, nm)), np.eye(nm)], [-Kk, np.zeros((nm, nm))]])
    Bu = np.zeros((nm, 3))
    for j in range(3):
        Bu[2 * j, j], Bu[2 * j + 1, j] = 1.0, -1.0
    Bc = np.vstack([np.zeros((nm, 3)), Bu])
    sysd = control.c2d(control.ss(Ac, Bc, np.eye(12), np.zeros((12, 3))), 0.5)
    s = load_system(DATA / "chain.toml")
    np.testing.assert_allclose(s.A, sysd.A, atol=1e-12)
    np.testing.assert_allclose(s.B, sysd.B, atol=1e-12)


NONLINEAR_LINES = [
    line.strip() for line in PAGE.splitlines() if "--system spring.toml" in line and "qsid sweep" in line
]


def test_the_nonlinear_plant_is_khalils_spring_and_loads_from_beside_its_file():
    """spring.toml's module sits beside it (no PYTHONPATH); its field is Khalil's m y'' + c y' + k(1 + a²y²)y = u."""
    import sys

    from qsid_core.plant import load_nonlinear

    assert ":files: spring.toml spring_field.py" in PAGE and len(NONLINEAR_LINES) == 2
    before = list(sys.path)
    s = load_nonlinear(DATA / "spring.toml")
    assert sys.path == before and (s.n, s.m, s.dt, s.x0) == (2, 1, 0.05, (1.5, 0.0))
    m, c, k, a = 1.0, 0.4, 1.0, 1.0
    rng = np.random.default_rng(0)
    x, u = rng.uniform(-2, 2, (50, 2)), rng.uniform(-1, 1, (50, 1))
    want = np.stack([x[:, 1], (u[:, 0] - c * x[:, 1] - k * (1 + a**2 * x[:, 0] ** 2) * x[:, 0]) / m], axis=1)
    np.testing.assert_allclose(s.xdot(x, u), want, rtol=1e-12)


@pytest.mark.slow
def test_the_nonlinear_plants_sweeps_say_what_the_page_says(capsys):
    """LS on its large-data limit up to b = 5 (within 5 %), BCLS's error several times lower at b = 2, 3."""
    assert "on its large-data limit (the lifted Theorem 1: a bias) up\nto b = 5" in PAGE
    res = {}
    for line in NONLINEAR_LINES:
        argv = [str(DATA / a) if a.endswith(".toml") else a for a in shlex.split(line)[1:]]
        assert main([*argv, "--json"]) == 0
        d = json.loads(capsys.readouterr().out)
        res[d["config"]["estimator"]] = {r["bits"]: r for r in d["results"]}
    for b, r in res["ls"].items():
        if b > 5:
            continue
        assert r["err_G"]["mean"] == pytest.approx(r["large_data"]["err_G"], rel=0.05), b
    for b in (2, 3):
        assert res["bcls"][b]["err_G"]["mean"] < res["ls"][b]["err_G"]["mean"] / 4, b
