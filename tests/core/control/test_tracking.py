"""Time-varying references with preview: exact against the condensed QP solved directly, CLI, bad input."""

import json

import numpy as np
import pytest

from app.cli import main
from qsid_core.control.closed_loop import run_closed_loops
from qsid_core.control.condensed_qp import condense
from qsid_core.control.mpc import MPCConfig
from qsid_core.control.reference import reference_samples
from qsid_core.control.riccati import dare_stabilizing
from qsid_core.errors import ConfigError
from qsid_core.plant.systems import get_system


def _direct(s, cfg, A_hat, B_hat):
    """The same MPC step by step: the condensed QP of (A^, B^) with the reference window, solved by DAQP."""
    import daqp

    w = cfg.resolve(s)
    N, n, m = cfg.horizon, s.n, s.m
    Qf = dare_stabilizing(A_hat, B_hat, w.Q, w.R)
    cq = condense(A_hat[None], B_hat[None], w.Q, w.R, Qf[None], np.zeros(n), N)
    ub = np.tile(w.u_max, N)
    x, xs = w.x0.copy(), [w.x0.copy()]
    Ku = np.linalg.pinv(B_hat) @ (np.eye(n) - A_hat)
    for t in range(cfg.steps):
        g = cq.Gx[0] @ x + cq.Gr[0] @ w.reference[t + 1 : t + 1 + N].reshape(-1)
        if cfg.tracking == "offset-free":  # -R u_ref,k on the rows of u_k
            g -= (w.reference[t : t + N] @ Ku.T @ w.R.T).reshape(-1)
        U, _, flag, _ = daqp.solve(
            np.ascontiguousarray(cq.H[0]), g, np.zeros((0, N * m)), ub, -ub, np.zeros(N * m, dtype=np.int32)
        )
        assert flag == 1
        x = s.A @ x + s.B @ np.clip(U[:m], -w.u_max, w.u_max)
        xs.append(x)
    return np.array(xs)


@pytest.mark.parametrize(
    "u_max, ref, form",
    [
        (100.0, "sine:1:1:40", "letter"),
        (0.3, "square:2:0.5:20", "letter"),
        (0.5, "step:theta:0.3:5", "letter"),
        (100.0, "sine:1:1:40", "offset-free"),
        (0.3, "square:4:0.5:20", "offset-free"),
    ],
)
def test_tracking_loop_is_the_condensed_qp_solved_step_by_step(u_max, ref, form):
    s = get_system("boeing747")
    rng = np.random.default_rng(0)
    A_hat, B_hat = s.A + 1e-3 * rng.standard_normal(s.A.shape), s.B + 1e-3 * rng.standard_normal(s.B.shape)
    cfg = MPCConfig(reference=ref, u_max=u_max, steps=40, verify_steps=None, tracking=form)
    lp = run_closed_loops([(A_hat, B_hat), (s.A, s.B)], s.A, s.B, cfg, s)
    np.testing.assert_allclose(lp.states[0], _direct(s, cfg, A_hat, B_hat), rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(lp.states[1], _direct(s, cfg, s.A, s.B), rtol=1e-7, atol=1e-9)
    if u_max < 1:
        assert lp.qp_steps > 0  # the constrained path (with the reference in g) was used
    assert lp.tracking_error.shape == (2,) and np.all(lp.tracking_error > 0)


@pytest.mark.slow
def test_boeing_sine_tracking_error_falls_to_the_true_models(capsys):
    assert main(["sweep", "--system", "boeing747", "--reference", "sine:1:1:40", "--json", "-q"]) == 0
    d = json.loads(capsys.readouterr().out)
    te = {r["bits"]: r["tracking_error"]["mean"] for r in d["results"]}
    true = d["tracking_error_true_model"]
    assert te[2] > te[4] > te[8] and abs(te[8] / true - 1) < 0.05
    assert d["config"]["mpc"]["reference"] == "sine:1:1:40"


def test_reference_forms():
    names = ("a", "b")
    r = reference_samples("step:b:2:3", names, 6)
    assert r[:, 0].tolist() == [0] * 6 and r[:, 1].tolist() == [0, 0, 0, 2, 2, 2]
    sq = reference_samples("square:1:1:4", names, 8)[:, 0]
    assert sq.tolist() == [1, 1, -1, -1, 1, 1, -1, -1]
    sn = reference_samples("sine:2:3:4", names, 5)[:, 1]
    np.testing.assert_allclose(sn, [0, 3, 0, -3, 0], atol=1e-12)
    held = reference_samples([[1, 2], [3, 4]], names, 4)
    assert held.tolist() == [[1, 2], [3, 4], [3, 4], [3, 4]]


@pytest.mark.parametrize(
    "spec, msg",
    [
        ("ramp:1:1:3", "must look like"),
        ("step:9:1:3", "1..2"),
        ("step:zz:1:3", "state name"),
        ("sine:1:1:1", "period"),
        ("step:1:x:3", "numbers"),
        ("step:1:1:-2", "step time"),
    ],
)
def test_bad_reference_specs(spec, msg):
    with pytest.raises(ConfigError, match=msg):
        reference_samples(spec, ("a", "b"), 5)


def test_reference_config_checks():
    with pytest.raises(ConfigError, match="not both"):
        MPCConfig(reference="sine:1:1:9", x_ref=(1.0,))
    with pytest.raises(ConfigError, match="daqp"):
        MPCConfig(reference="sine:1:1:9", solver="osqp")
    with pytest.raises(ConfigError, match="finite"):
        MPCConfig(reference=((1.0, float("nan")),))


def test_cli_reference_file_and_bad_input(tmp_path, capsys):
    f = tmp_path / "ref.csv"
    f.write_text("angle,speed,current\n" + "\n".join("0.5,0,0" for _ in range(20)) + "\n")
    base = ["sweep", "--bits", "8", "--realizations", "2", "--trajectories", "20", "--steps", "100", "-q", "--json"]
    assert main([*base, "--reference", str(f)]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["config"]["mpc"]["reference"][0] == [0.5, 0.0, 0.0] and d["results"][0]["tracking_error"]["mean"] > 0
    bad = tmp_path / "bad.csv"
    bad.write_text("1,2\n3,4\n")
    for args, msg in (
        (["--reference", str(bad)], "3 columns"),
        (["--reference", "nofile.csv"], "neither"),
        (["--reference", "sine:7:1:10"], "1..3"),
        (["--reference", "sine:1:1:10", "--x-ref", "1"], "exclude each other"),
    ):
        assert main([*base, *args]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and msg in err, err


def test_offset_free_form_removes_the_offset_at_an_equilibrium_reference():
    s = get_system("boeing747")
    u_bar = np.array([0.05, -0.02])
    x_eq = np.linalg.solve(np.eye(4) - s.A, s.B @ u_bar)  # an equilibrium of the true plant
    out = {}
    for form in ("letter", "offset-free"):
        cfg = MPCConfig(x_ref=tuple(x_eq), tracking=form, steps=400, u_max=10.0, verify_steps=None)
        out[form] = np.linalg.norm(run_closed_loops([(s.A, s.B)], s.A, s.B, cfg, s).states[0, -1] - x_eq)
    assert out["offset-free"] < 1e-6 < 1e-2 < out["letter"]
    # a time-varying reference in the offset-free form is still the condensed QP solved exactly
    cfg = MPCConfig(reference="step:theta:0.2:5", tracking="offset-free", steps=30, u_max=0.4, verify_steps=None)
    lp = run_closed_loops([(s.A, s.B)], s.A, s.B, cfg, s)
    assert np.isfinite(lp.states).all() and lp.outcome == []
    with pytest.raises(ConfigError, match="tracking"):
        MPCConfig(tracking="smooth")


def test_dashboard_draws_the_reference_in_3d_and_in_the_time_series():
    from app.dashboard.session import iter_frames
    from app.figures.phase_scene import scene_view
    from app.frames.cache import SharedCache
    from app.frames.render import build_figures
    from app.settings.values import Values

    small = dict(realizations=3, trajectories=20, steps=100, identification="LS")
    fr = list(
        iter_frames(
            Values(system="boeing747", bits=8, reference="sine:u:1:20", **small),
            SharedCache(),
            chunk=16,
            min_interval=0.0,
        )
    )
    v = scene_view(fr[-1])
    assert v.ref_segments.shape == (50, 2, 3) and np.isfinite(v.ref_segments).all()
    ts = build_figures(fr[-1], ["timeseries"])["timeseries"]
    ref = [d for d in ts.data if d.name == "reference"]
    assert len(ref) == 1 and len(ref[0].y) == 51 and max(ref[0].y) == pytest.approx(1.0, abs=0.01)
    plain = list(iter_frames(Values(system="boeing747", bits=8, **small), SharedCache(), chunk=16, min_interval=0.0))
    assert scene_view(plain[-1]).ref_segments.shape == (0, 2, 3)
