"""Every public engine entry point raises only the engine's own error class.

A hypothesis test per entry point not already fuzzed in ``test_engine_inputs.py``, and the three findings of
the issue's 78,000-example hunt as plain regression tests. Each call is watched: an exception that is not a
:class:`~qsid_core.errors.QsidError` fails, a call that runs past :data:`support.FUZZ_HANG_S` fails as a hang, and a result
with a NaN that is not flagged fails.

``QSID_FUZZ_EXAMPLES=N QSID_FUZZ_RANDOM=1`` runs a longer, randomized hunt; ``QSID_FUZZ_REPORT=FILE`` writes
what every call gave, per entry point (``benchmarks/fuzz_engine.py`` does both and prints the counts).
"""

from __future__ import annotations

import json
import math
import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from support import fuzz_call, fuzz_no_nan

from qsid_core import (
    DataLengthConfig,
    LTISystem,
    MPCConfig,
    QsidError,
    QuantizerSpec,
    SweepConfig,
    dataset_from_arrays,
    dc_motor,
    identify,
    identify_recorded,
    prepare,
    quantized_moments,
    quantizer_demo,
    realized_bounds,
    riccati_finite,
    run_datalength,
    run_sweep,
    simulate,
    theorem1_prediction,
)

FUZZ = settings(
    max_examples=int(os.environ.get("QSID_FUZZ_EXAMPLES", "40")),
    deadline=None,
    derandomize=os.environ.get("QSID_FUZZ_RANDOM") != "1",
    database=None,
    suppress_health_check=list(HealthCheck),
)

# ------------------------------------------------------------------------------------------------
# the three findings
# ------------------------------------------------------------------------------------------------


def test_a_loop_sitting_on_its_reference_with_a_negligible_q_is_judged_not_divided_by_zero():
    res = run_sweep(
        SweepConfig(
            system=dc_motor(), bits=(4,), realizations=2, trajectories=5, steps=30, mpc=MPCConfig(Q=1e-100, x0=0.0)
        )
    )
    out = res.loops[4].outcome
    assert list(out) == ["converged", "converged"]  # x stays exactly at x_ref = 0


def test_a_system_file_with_zero_x0_and_tiny_q_runs_from_the_cli(tmp_path, capsys):
    from app.cli import main

    f = tmp_path / "q.toml"
    f.write_text("A = [[1.0, 0.1, 0.0], [0.0, 1.0, 0.1], [0.0, 0.0, 0.9]]\nB = [[0.0], [0.0], [0.1]]\n")
    f.write_text(f.read_text() + "x0 = [0, 0, 0]\nQ = [1e-20, 1e-20, 1e-20]\n")
    code = main(["sweep", "--system", str(f), "--bits", "4", "--realizations", "2", "--trajectories", "5", "-q"])
    _, err = capsys.readouterr()
    assert code == 0 and "Traceback" not in err, err


def test_negligible_input_weights_give_no_bound_not_a_linalg_error():
    s = LTISystem(name="x", A=[[0.1385]], B=[[0.0, 0.1385]], R=[1e-300, 1e-300])
    cfg = SweepConfig(
        system=s,
        bits=(1, 20),
        realizations=3,
        trajectories=20,
        steps=100,
        estimator="bcls",
        quantizer=QuantizerSpec(range_mode="fixed", fixed_range=(0.0, 1.0)),
    )
    res = run_sweep(cfg)
    for b in cfg.bits:
        th = res.theory[b]
        assert math.isfinite(th.delta) or th.bound_note


def test_the_batched_riccati_recursion_gives_nan_for_a_singular_problem_only():
    from qsid_core.control.realized_bound import _riccati_finite_batch

    A = np.array([[[0.5]], [[0.5]]])
    B = np.array([[[1.0, 0.0]], [[1.0, 1.0]]])  # the second input moves nothing in the first model
    R = np.diag([1.0, 0.0])  # and costs nothing: R + B'PB is singular there
    P = _riccati_finite_batch(A, B, np.eye(1), R, np.stack([np.eye(1)] * 2), 3)
    assert np.isnan(P[0]).all()
    assert np.isfinite(P[1]).all()


def test_data_too_large_for_memory_is_an_engine_error_saying_how_large():
    with pytest.raises(QsidError, match=r"would need [\d.]+ GiB .*use fewer trajectories or steps"):
        simulate(dc_motor(), 100_000, 6593, None)


# ------------------------------------------------------------------------------------------------
# fuzz, one test per entry point
# ------------------------------------------------------------------------------------------------

entry = st.one_of(
    st.floats(-2.0, 2.0, allow_nan=False),
    st.sampled_from([0.0, 1.0, -1.0, 1e-300, 1e-12, 1e12, 1e300, float("nan"), float("inf")]),
)
weight = st.sampled_from([1e-300, 1e-100, 1e-20, 1e-8, 1.0, 1e8, 1e100, 0.0, -1.0, float("nan")])


@st.composite
def small_system(draw):
    n, m = draw(st.integers(1, 3)), draw(st.integers(1, 2))
    A = draw(st.lists(st.lists(entry, min_size=n, max_size=n), min_size=n, max_size=n))
    B = draw(st.lists(st.lists(entry, min_size=m, max_size=m), min_size=n, max_size=n))
    kw = {}
    if draw(st.booleans()):
        kw["Q"] = [draw(weight)] * n
    if draw(st.booleans()):
        kw["R"] = [draw(weight)] * m
    if draw(st.booleans()):
        kw["x0"] = [draw(st.sampled_from([0.0, 1.0, -3.0, 1e-300]))] * n
    return fuzz_call("LTISystem", LTISystem, "fuzz", A, B, **kw)


@FUZZ
@given(
    s=small_system(),
    trajectories=st.sampled_from([1, 2, 5, 100_000, 10**9, 0, -1]),
    steps=st.sampled_from([1, 3, 20, 1_000_000, 10**7, 0]),
    amplitude=st.sampled_from([1.0, 1e-300, 1e12, 0.0, float("nan")]),
)
@pytest.mark.slow
def test_fuzz_simulate(s, trajectories, steps, amplitude):
    if s is None:
        return
    d = fuzz_call("simulate", simulate, s, trajectories, steps, 0, amplitude)
    if trajectories * steps >= 10**11:  # terabytes: refused before anything is allocated
        assert d is None
    if d is not None:
        fuzz_no_nan("simulate", d.states, d.inputs)


@FUZZ
@given(
    s=small_system(),
    bits=st.lists(st.integers(-1, 40), min_size=1, max_size=3),
    dither=st.sampled_from(["subtractive", "tpdf", "rpdf", "none", "bad"]),
    range_mode=st.sampled_from(["per-channel", "shared", "fixed"]),
    fixed=st.tuples(st.sampled_from([-1e300, -1.0, 0.0]), st.sampled_from([1e-300, 1.0, 1e300])),
    estimator=st.sampled_from(["ls", "bcls", "nope"]),
)
@pytest.mark.slow
def test_fuzz_moments_and_identify(s, bits, dither, range_mode, fixed, estimator):
    if s is None:
        return
    d = fuzz_call("simulate", simulate, s, 3, 20, 0)
    spec = fuzz_call(
        "QuantizerSpec",
        QuantizerSpec,
        dither=dither,
        range_mode=range_mode,
        fixed_range=fixed if range_mode == "fixed" else None,
    )
    if d is None or spec is None:
        return
    prep = fuzz_call("prepare", prepare, d, spec)
    if prep is None:
        return
    moms = fuzz_call("quantized_moments", quantized_moments, prep, bits, spec, np.random.default_rng(0))
    for mom in moms or []:
        ident = fuzz_call("identify", identify, mom, estimator)
        if ident is not None:
            G = np.hstack([ident.A, ident.B])
            assert np.all(np.isfinite(G)) or ident.note, "a non-finite model without a note"


@FUZZ
@given(
    G=st.lists(st.lists(entry, min_size=3, max_size=3), min_size=2, max_size=2),
    sigma=st.sampled_from([1.0, 1e-300, 0.0, 1e300, -1.0, float("nan")]),
    eps=st.lists(st.sampled_from([0.1, 0.0, 1e-300, 1e300, -1.0, float("inf")]), min_size=3, max_size=3),
    dither=st.sampled_from(["subtractive", "tpdf", "rpdf", "none", "x"]),
)
@pytest.mark.slow
def test_fuzz_theorem1_prediction(G, sigma, eps, dither):
    out = fuzz_call("theorem1_prediction", theorem1_prediction, np.array(G), sigma * np.eye(3), np.array(eps), dither)
    if out is not None:
        fuzz_no_nan("theorem1_prediction", out)


@FUZZ
@given(
    a=st.lists(entry, min_size=4, max_size=4),
    b=st.lists(entry, min_size=4, max_size=4),
    q=weight,
    r=weight,
    horizon=st.sampled_from([1, 5, 0, -1]),
    theta=st.sampled_from([0.5, 1e-300, 1.0, 0.0]),
    with_qf=st.booleans(),
)
@pytest.mark.slow
def test_fuzz_bounds(a, b, q, r, horizon, theta, with_qf):
    A = np.array(a).reshape(2, 2)
    B = np.array(b).reshape(2, 2)
    Q, R = q * np.eye(2), r * np.eye(2)
    fuzz_call("riccati_finite", riccati_finite, A, B, Q, R, np.eye(2), horizon)
    models = [(A, B), (0.9 * A, B)]
    rb = fuzz_call(
        "realized_bounds",
        realized_bounds,
        models,
        A,
        B,
        Q,
        R,
        np.eye(2) if with_qf else None,
        horizon,
        theta=theta,
    )
    if rb is not None:
        assert rb.delta.shape == (2,)


@FUZZ
@given(
    s=small_system(),
    bits=st.integers(-1, 40),
    samples=st.lists(st.sampled_from([1, 10, 100, 1000, 0, 10**12]), min_size=1, max_size=3),
    realizations=st.integers(0, 3),
)
@pytest.mark.slow
def test_fuzz_run_datalength(s, bits, samples, realizations):
    if s is None:
        return
    cfg = fuzz_call(
        "DataLengthConfig",
        DataLengthConfig,
        system=s,
        bits=bits,
        samples=tuple(samples),
        realizations=realizations,
        steps_per_run=50,
        min_runs=1,
    )
    if cfg is not None:
        res = fuzz_call("run_datalength", run_datalength, cfg)
        if res is not None:
            json.dumps(res.to_dict(), allow_nan=False)


@FUZZ
@given(
    signal_=st.lists(entry, min_size=0, max_size=50),
    lo=st.sampled_from([-1.0, 0.0, 1.0, -1e300, float("nan")]),
    hi=st.sampled_from([1.0, 0.0, 1e300, float("inf")]),
    bits=st.integers(-1, 40),
    window=st.sampled_from([1, 10, 200, 0]),
)
@pytest.mark.slow
def test_fuzz_quantizer_demo(signal_, lo, hi, bits, window):
    out = fuzz_call("quantizer_demo", quantizer_demo, np.array(signal_), lo, hi, bits, window=window)
    if out is not None:
        fuzz_no_nan("quantizer_demo", out.var_dithered, out.var_plain)


@FUZZ
@given(
    T=st.integers(0, 40),
    n=st.integers(1, 3),
    m=st.integers(1, 2),
    fill=entry,
    bits=st.sampled_from(["2:8", "4", "0", "1:40", "x"]),
    realizations=st.integers(0, 3),
)
@pytest.mark.slow
def test_fuzz_recorded(T, n, m, fill, bits, realizations):
    rng = np.random.default_rng(0)
    x = rng.uniform(-1, 1, (T + 1, n))
    u = rng.uniform(-1, 1, (T, m))
    if T:
        x[T // 2, 0] = fill
    data = fuzz_call("dataset_from_arrays", dataset_from_arrays, x, u)
    if data is not None:
        res = fuzz_call("identify_recorded", identify_recorded, data, bits=bits, realizations=realizations)
        if res is not None:
            json.dumps(res.to_dict(), allow_nan=False)


@FUZZ
@given(
    s=small_system(),
    q=weight,
    r=weight,
    x0=st.sampled_from([0.0, 1.0, 1e-300, None]),
    estimator=st.sampled_from(["ls", "bcls"]),
    u_max=st.sampled_from([None, 1e-300, 0.5, 1e300]),
)
@pytest.mark.slow
def test_fuzz_run_sweep_degenerate_weights(s, q, r, x0, estimator, u_max):
    if s is None:
        return
    mpc = fuzz_call("MPCConfig", MPCConfig, horizon=3, steps=8, Q=q, R=r, x0=x0, u_max=u_max)
    if mpc is None:
        return
    cfg = fuzz_call(
        "SweepConfig",
        SweepConfig,
        system=s,
        bits=(1, 6, 20),
        realizations=2,
        trajectories=3,
        steps=max(20, s.n + s.m),
        estimator=estimator,
        mpc=mpc,
    )
    if cfg is None:
        return
    res = fuzz_call("run_sweep", run_sweep, cfg)
    if res is not None:
        json.dumps(res.to_dict(), allow_nan=False)


def _plant_text(suffix: str, depth: int, opener: str, digits: int, key: str) -> str:
    """A plant file's text: ``key`` holding a value nested ``depth`` deep (``opener``: a list or a table) around a
    number of ``digits`` digits."""
    number = "9" * digits
    if suffix == ".json":
        inner = "[" * depth + number + "]" * depth if opener == "[" else '{"a": ' * depth + number + "}" * depth
        return '{"' + key + '": ' + inner + ', "B": [[1]]}'
    inner = "[" * depth + number + "]" * depth if opener == "[" else "{a = " * depth + number + "}" * depth
    return f"{key} = {inner}\nB = [[1]]\n"


@FUZZ
@given(
    suffix=st.sampled_from([".json", ".toml"]),
    depth=st.sampled_from([1, 2, 3, 50, 500, 999, 1000, 1001, 5000]),
    opener=st.sampled_from(["[", "{"]),
    digits=st.sampled_from([1, 300, 4300, 4301, 20000]),
    key=st.sampled_from(["A", "x0", "vector_field", "n"]),
    junk=st.binary(max_size=64),
)
def test_fuzz_plant_files(suffix, depth, opener, digits, key, junk):
    """Deep nesting, long numbers and stray bytes: every public plant-file reader answers or raises an engine
    error (a SystemDefinitionError, not RecursionError, OSError or a hang)."""
    import tempfile
    from pathlib import Path

    from qsid_core import get_system, load_system
    from qsid_core.plant import is_nonlinear, is_nonlinear_file, load_nonlinear

    with tempfile.TemporaryDirectory() as tmp:
        p = Path(tmp) / f"plant{suffix}"
        p.write_bytes(_plant_text(suffix, depth, opener, digits, key).encode() + junk)
        for name, fn in (
            ("load_system", load_system),
            ("get_system", get_system),
            ("is_nonlinear_file", is_nonlinear_file),
            ("is_nonlinear", is_nonlinear),
            ("load_nonlinear", load_nonlinear),
        ):
            fuzz_call(name, fn, str(p))
