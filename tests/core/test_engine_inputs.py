"""Engine API robustness (issue 11, "Input" and "Engine API").

Every engine entry point either returns finite numbers (failures flagged as such)
or raises a :class:`qsid_core.errors.QsidError` (a ValueError) naming the field and
what is allowed -- never another exception type, never a silent NaN/inf.

The first part pins each repro of the issue; the second fuzzes the API with
hypothesis (derandomized, no example database: the same examples every run).
"""

from __future__ import annotations

import datetime
import json
import math
import os
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from support import fuzz_call

from qsid_core import (
    ConfigError,
    LTISystem,
    MPCConfig,
    QuantizerSpec,
    SweepConfig,
    SystemDefinitionError,
    get_system,
    load_system,
    parse_bits,
    quantize,
    run_sweep,
)
from qsid_core.control.bound import ultimate_bound
from qsid_core.control.riccati import dare_stabilizing
from qsid_core.errors import check_float, check_int
from qsid_core.identification.identify import relative_errors
from qsid_core.plant.data import simulate
from qsid_core.plant.systems import dc_motor, dc_motor_physical, system_from_dict
from qsid_core.studies.experiment import Experiment
from qsid_core.validate import parse_matrix

TINY = dict(trajectories=2, steps=20, realizations=2, bits=(2, 4))


def nested(depth: int):
    v: object = 1.0
    for _ in range(depth):
        v = [v]
    return v


def _sys(**kw):
    base = dict(A=[[0.5]], B=[[1.0]])
    base.update(kw)
    return lambda: LTISystem("s", **base)


def _file(tmp: Path, name: str, text: str):
    p = tmp / name
    p.write_text(text, encoding="utf-8")
    return lambda: load_system(p)


BIG = "1" + "0" * 400

# (id, callable, expected error class, regex the message must match)
SYSTEM_CASES = [
    ("A-dict", _sys(A=[[{}]]), "A must be a matrix of numbers.*table/object"),
    ("A-string", _sys(A=[["1"]]), r"A must be a matrix of numbers.*row 1, column 1 is text '1'"),
    ("A-true", _sys(A=[[True]]), r"A must be a matrix.*true/false"),
    ("A-nan", _sys(A=[[float("nan")]]), "A must contain only finite numbers"),
    ("A-inf", _sys(A=[[float("inf")]]), "A must contain only finite numbers"),
    ("A-int-400-digits", _sys(A=[[10**400]]), "A: row 1, column 1 is an integer with about 401 digits"),
    ("A-1e300", _sys(A=[[1e300]]), r"A: entries must be at most 1e\+12 in magnitude"),
    ("A-empty", _sys(A=[]), "A must not be empty"),
    ("A-5000-nested", _sys(A=nested(5000)), "A must be a matrix.*nested deeper than 2"),
    ("A-ragged", _sys(A=[[1, 2], [3]]), "same number of entries"),
    ("A-and-B-zero", _sys(A=[[0.0]], B=[[0.0]]), "both \\(nearly\\) all zeros"),
    ("A-0-B-1e-300", _sys(A=[[0.0]], B=[[1e-300]]), "nothing to identify"),
    ("x0-dict", _sys(x0={"a": 1}), "x0 must be .*table/object"),
    ("x0-huge-int", _sys(x0=[10**400]), "x0: entry .* too large"),
    ("Q-date", _sys(Q=datetime.date(1979, 5, 27)), "Q must be .*date/time"),
    ("Q-huge-int", _sys(Q=[10**400]), "Q: entry .* too large"),
    ("dt-nan", _sys(dt=float("nan")), "dt .* positive, finite number of seconds; got nan"),
    ("dt-minus-5", _sys(dt=-5), "dt .* positive, finite number of seconds; got -5"),
    ("dt-text", _sys(dt="1"), "dt .* positive"),
    ("name-dict", lambda: LTISystem({"x": 1}, [[0.5]], [[1.0]]), "system name must be text"),
    ("name-300-chars", lambda: get_system("a" * 300), "unknown system .*not a preset .*not an existing"),
    ("name-300-chars.json", lambda: get_system("a" * 300 + ".json"), "cannot be opened .*File name too long"),
    ("name-NUL", lambda: get_system("a\0b.toml"), "cannot be opened"),
    ("system-not-text", lambda: get_system(3), "system must be a preset name"),
    ("system-dir", lambda: get_system("/tmp"), "'/tmp' is a directory, not a system file"),
    ("load-dir", lambda: load_system("/tmp"), "is a directory"),
    ("system-missing", lambda: load_system("/nonexistent/x.toml"), "does not exist"),
    ("from-dict-null-Q", lambda: system_from_dict({"A": [[0.5]], "B": [[1.0]], "Q": None}), "Q is empty"),
    ("physical-dt-text", lambda: dc_motor_physical("a"), "dt must be a number"),
    ("physical-dt-nan", lambda: dc_motor_physical(float("nan")), "dt must be finite"),
    ("parse_matrix-not-text", lambda: parse_matrix(3, "A"), "A must be text"),
    ("parse_matrix-5000-brackets", lambda: parse_matrix("[" * 5000 + "1" + "]" * 5000, "A"), "nested too deeply"),
    ("parse_matrix-1e400", lambda: parse_matrix("1e400 1", "A"), "only finite numbers"),
]


@pytest.mark.parametrize("case, fn, match", SYSTEM_CASES, ids=[c[0] for c in SYSTEM_CASES])
def test_system_repros_raise_clear_errors(case, fn, match):
    with pytest.raises(SystemDefinitionError, match=match):
        fn()


FILE_CASES = [
    ("toml-date-as-Q", "s.toml", "A = [[0.5]]\nB = [[1.0]]\nQ = 1979-05-27\n", "Q must be .*date/time"),
    ("toml-A-true", "s.toml", "A = [[true]]\nB = [[1.0]]\n", "A must be .*true/false"),
    ("toml-dt-nan", "s.toml", "A = [[0.5]]\nB = [[1.0]]\ndt = nan\n", "dt .* got nan"),
    ("json-object-as-Q", "s.json", '{"A": [[0.5]], "B": [[1.0]], "Q": {"a": 1}}', "Q must be .*table/object"),
    ("json-object-as-x0", "s.json", '{"A": [[0.5]], "B": [[1.0]], "x0": {"a": 1}}', "x0 must be .*table/object"),
    ("json-1e400-int-in-A", "s.json", '{"A": [[' + BIG + ']], "B": [[1.0]]}', "A: row 1, column 1 is an .*401 digits"),
    ("json-1e400-int-in-x0", "s.json", '{"A": [[0.5]], "B": [[1.0]], "x0": [' + BIG + "]}", "x0: entry .*401 digits"),
    ("json-dt-minus-5", "s.json", '{"A": [[0.5]], "B": [[1.0]], "dt": -5}', "dt .* got -5"),
    (
        "json-5000-nested",
        "s.json",
        '{"A": ' + "[" * 5000 + "1" + "]" * 5000 + ', "B": [[1]]}',
        "nested too deeply|nested deeper",
    ),
    ("json-name-object", "s.json", '{"A": [[0.5]], "B": [[1.0]], "name": {"x": 1}}', "system name must be text"),
    ("json-top-level-list", "s.json", "[1, 2]", "table/object with keys A and B"),
    ("bad-suffix", "s.yaml", "A: 1", "must end in .toml or .json"),
]


@pytest.mark.parametrize("case, name, text, match", FILE_CASES, ids=[c[0] for c in FILE_CASES])
def test_system_file_repros_raise_clear_errors(tmp_path, case, name, text, match):
    with pytest.raises(SystemDefinitionError, match=match):
        _file(tmp_path, name, text)()


CONFIG_CASES = [
    ("SweepConfig-mpc-3", lambda: SweepConfig(mpc=3), "mpc must be an MPCConfig, or None"),
    ("SweepConfig-system-3", lambda: SweepConfig(system=3), "system must be a preset name"),
    ("SweepConfig-rho-1e300", lambda: SweepConfig(rho=1e300), r"rho must be in \(0, 1e\+12\]; got 1e\+300"),
    ("SweepConfig-theta-huge-int", lambda: SweepConfig(theta=10**400), "theta is too large"),
    ("SweepConfig-theta-nan", lambda: SweepConfig(theta=float("nan")), "theta must be finite"),
    ("SweepConfig-realizations-true", lambda: SweepConfig(realizations=True), "realizations must be an integer"),
    ("SweepConfig-steps-array", lambda: SweepConfig(steps=np.array([1, 2])), "steps must be an integer"),
    ("SweepConfig-quantizer-None", lambda: SweepConfig(quantizer=None), "quantizer must be a QuantizerSpec"),
    ("SweepConfig-estimator-array", lambda: SweepConfig(estimator=np.array(["ls", "ls"])), "estimator must be one of"),
    ("parse_bits-1:9x30", lambda: parse_bits("1:" + "9" * 30), "bits range end must be between 1 and 32"),
    ("parse_bits-1:9x18", lambda: parse_bits("1:" + "9" * 18), "bits range end must be between 1 and 32"),
    ("parse_bits-9x30:1:1", lambda: parse_bits("9" * 30 + ":" + "9" * 31 + ":1"), "between 1 and 32"),
    ("parse_bits-5000-digits", lambda: parse_bits("9" * 5000), "bits must look like"),
    ("parse_bits-huge-range", lambda: parse_bits(range(1, 10**30)), "at most a few dozen"),
    ("parse_bits-None", lambda: parse_bits(None), "bits must look like"),
    ("parse_bits-empty", lambda: parse_bits([]), "at least one word length"),
    (
        "QuantizerSpec-range-1e308",
        lambda: QuantizerSpec(range_mode="fixed", fixed_range=(-1e308, 1e308)),
        "hi - lo overflows",
    ),
    (
        "QuantizerSpec-range-5e-324",
        lambda: QuantizerSpec(range_mode="fixed", fixed_range=(0, 5e-324)),
        "hi - lo = .* is too small",
    ),
    ("QuantizerSpec-range-dict", lambda: QuantizerSpec(range_mode="fixed", fixed_range={"a": 1}), "table/object"),
    ("QuantizerSpec-range-huge-int", lambda: QuantizerSpec(range_mode="fixed", fixed_range=(0, 10**400)), "too large"),
    ("QuantizerSpec-guard-text", lambda: QuantizerSpec(guard="yes"), "guard must be True or False"),
    ("quantize-range-1e308", lambda: quantize(np.zeros(3), -1e308, 1e308, 4), "hi - lo overflows"),
    ("quantize-range-5e-324", lambda: quantize(np.zeros(3), 0.0, 5e-324, 4), "too small"),
    ("quantize-x-nan", lambda: quantize(np.array([np.nan]), 0.0, 1.0, 4), "x .* only finite numbers"),
    ("quantize-x-text", lambda: quantize("abc", 0.0, 1.0, 4), "x .* text"),
    (
        "quantize-dither-shape",
        lambda: quantize(np.zeros(3), 0.0, 1.0, 2, unit_dither=np.zeros(5)),
        "unit_dither must have the shape of x",
    ),
    ("quantize-rng-int", lambda: quantize(np.zeros(3), 0.0, 1.0, 2, rng=3), "rng must be a numpy Generator"),
    ("quantize-lo-shape", lambda: quantize(np.zeros((4, 3)), np.zeros(2), np.ones(2), 2), "one per channel"),
    ("quantize-hi-widens-x", lambda: quantize([0.0], 0.0, np.array([1.0, 2.0]), 1), "one per channel"),
    ("MPCConfig-Q-empty", lambda: MPCConfig(Q=[]), "Q must not be empty"),
    ("MPCConfig-u_max-dict", lambda: MPCConfig(u_max={"a": 1}), "u_max must be a list of numbers"),
    ("MPCConfig-u_max-huge-int", lambda: MPCConfig(u_max=10**400), "u_max: it is an integer .* too large"),
    ("MPCConfig-u_max-1e308", lambda: MPCConfig(u_max=1e308), "at most 1e\\+12"),
    ("MPCConfig-x0-nested", lambda: MPCConfig(x0=nested(5000)), "x0 must be a list of numbers; it is nested"),
    ("MPCConfig-eps-true", lambda: MPCConfig(eps=True), "OSQP eps must be a number"),
    ("check_int-array", lambda: check_int("n", np.array([1, 2]), 0), "n must be an integer"),
    ("check_float-text", lambda: check_float("x", "1.5"), "x must be a number"),
    ("simulate-seed-text", lambda: simulate(dc_motor(), 2, 5, seed="a"), "seed must be an integer"),
    ("simulate-not-a-system", lambda: simulate("dc-motor", 2, 5), "system must be an LTISystem"),
    ("run_sweep-not-a-config", lambda: run_sweep({"bits": 3}), "config must be a SweepConfig"),
    ("run_sweep-progress-not-callable", lambda: run_sweep(SweepConfig(**TINY), progress=3), "progress must be"),
    ("run_sweep-executor-junk", lambda: run_sweep(SweepConfig(**TINY), executor="pool"), "executor must be"),
    ("Experiment-not-a-config", lambda: Experiment("dc-motor"), "config must be a SweepConfig"),
]


@pytest.mark.parametrize("case, fn, match", CONFIG_CASES, ids=[c[0] for c in CONFIG_CASES])
def test_config_repros_raise_clear_errors(case, fn, match):
    # (parse_bits used to build the 10**18-element range before checking it: MemoryError after ~15 s)
    with pytest.raises(ConfigError, match=match):
        fn()


def test_zero_A_has_finite_relative_error_relative_to_the_whole_model():
    # A = 0: ||A - A^|| / ||A|| was inf; it is now relative to ||[A, B]|| (documented in relative_errors)
    eA, eB = relative_errors(np.array([[0.1]]), np.array([[1.0]]), np.array([[0.0]]), np.array([[2.0]]))
    assert eA == pytest.approx(0.1 / 2.0) and eB == 0.5
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        z = LTISystem("zero", [[0.0]], [[1.0]])
    res = run_sweep(SweepConfig(system=z, mpc=None, **TINY))
    for b in res.bits:
        assert np.all(np.isfinite(res.identification[b].err_A)) and math.isfinite(res.theory[b].err_A)
    json.dumps(res.to_dict(), allow_nan=False)


def test_infinite_bound_always_comes_with_a_note():
    P, Q, R = np.eye(2), np.eye(2), np.eye(1)
    dA, dB = np.ones((2, 2)), np.ones((2, 1))
    ub = ultimate_bound(P, Q, R, dA, dB, theta=5e-324, rho=1e12)  # theta*alpha1 underflows: was ZeroDivisionError
    assert ub.delta == math.inf and "overflows" in ub.note
    ub = ultimate_bound(-np.eye(2), Q, R, dA, dB)
    assert ub.delta == math.inf and "not positive definite" in ub.note
    ub = ultimate_bound(P, Q, R, dA * 1e-3, dB * 1e-3, rho=2.0)
    assert math.isfinite(ub.delta) and ub.note == ""


def test_rho_at_its_limit_gives_a_bound_or_a_noted_inf_in_a_sweep():
    res = run_sweep(SweepConfig(rho=1e12, mpc=MPCConfig(steps=3), **TINY))
    for b in res.bits:
        th = res.theory[b]
        assert math.isfinite(th.delta) or th.bound_note
    json.dumps(res.to_dict(), allow_nan=False)


def test_dare_singular_is_an_mpc_failure_not_linalgerror():
    # R + B'XB singular after the solve: used to escape as LinAlgError "Singular matrix"
    from qsid_core.errors import MPCFailure

    with pytest.raises(MPCFailure):
        dare_stabilizing(np.array([[2.0]]), np.array([[0.0]]), np.eye(1), np.eye(1))


def test_dare_singular_in_a_batch_does_not_escape_run_sweep():
    # found by the fuzz: one model with singular R + B'XB made the batched DARE raise "Singular matrix"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        s = LTISystem("f", [[0.0]], [[0.0, -1e11]])
    res = run_sweep(
        SweepConfig(
            system=s,
            bits=(2,),
            trajectories=1,
            steps=3,
            realizations=1,
            theta=1e-300,
            mpc=MPCConfig(horizon=1, steps=1, u_max=1e-6),
        )
    )
    _check_sweep(res)


def test_singular_lq_recursion_is_a_recorded_mpc_failure():
    # found by the fuzz: a singular R + B'PB in the batched LQ recursion raised LinAlgError out of run_sweep
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        s = LTISystem("f", [[1e6]], [[0.0, 0.0]])
    res = run_sweep(
        SweepConfig(
            system=s,
            bits=(9,),
            trajectories=3,
            steps=2,
            realizations=1,
            theta=1e-300,
            quantizer=QuantizerSpec(dither="none"),
            mpc=MPCConfig(horizon=2, steps=1, u_max=1e-6),
        )
    )
    _check_sweep(res)
    # the batched recursion solves per model (riccati._solve_each), so this nearly singular model now gets a
    # finite MPC instead of an exception; a truly singular one is recorded as kind 'dare' (test_riccati)
    assert res.loops[9].failure == [""] and np.isfinite(res.loops[9].cost).all()


def test_osqp_setup_rejection_is_a_recorded_mpc_failure():
    # found by the fuzz: OSQPException(4) (non-convex KKT) escaped run_sweep
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        s = LTISystem("f", [[0.0, 1.1875, 1.0], [1e6, 0.0, 1e6], [0.0, 0.0, 0.0]], [[0.0, 1.0], [0.0, 0.0], [1.0, 1.0]])
    res = run_sweep(
        SweepConfig(
            system=s,
            bits=(1,),
            trajectories=3,
            steps=2,
            realizations=1,
            theta=1e-300,
            mpc=MPCConfig(horizon=1, steps=1, u_max=1e-6),
        )
    )
    _check_sweep(res)


def test_theory_singular_riccati_is_recorded_not_raised(monkeypatch):
    import qsid_core.studies.theory_stage as exp

    def singular(*a, **k):
        raise np.linalg.LinAlgError("Singular matrix")

    monkeypatch.setattr(exp, "riccati_finite", singular)
    ex = Experiment(SweepConfig(mpc=MPCConfig(steps=3), **TINY))
    th = ex.theory(2)
    assert th.delta == math.inf and "Riccati recursion" in th.bound_note and "Singular" not in th.bound_note


def test_failed_identifications_are_flagged_never_silent_nan():
    # constant data at one realization cannot be identified: failed=True with a note, not NaN with failed=False,
    # and no numpy warning on the way (a user's terminal would show it)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        res = run_sweep(
            SweepConfig(
                bits=(1,),
                trajectories=1,
                steps=10,
                realizations=2,
                mpc=MPCConfig(steps=2),
                quantizer=QuantizerSpec(range_mode="fixed", fixed_range=(1e6, 1e6 + 1), dither="none"),
            )
        )
    _check_sweep(res)
    ident = res.identification[1]
    assert ident.failed.all() and ident.notes


def test_a_gram_matrix_whose_scaling_overflows_is_singular_without_a_warning():
    from qsid_core.errors import IdentificationError
    from qsid_core.identification.identify import least_squares

    PP = np.array([[1e-300, 1e10], [1e10, 1e-300]])  # scaled by its tiny diagonal, its entries overflow
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        with pytest.raises(IdentificationError, match="singular"):
            least_squares(PP, np.ones((1, 2)), 1)


# ------------------------------------------------------------------------------------------------
# fuzz: any input gives a result with finite (or flagged) numbers, or a QsidError
# ------------------------------------------------------------------------------------------------
# ------------------------------------------------------------------------------------------------

#: QSID_FUZZ_EXAMPLES=2000 QSID_FUZZ_RANDOM=1 runs a longer, randomized hunt (the suite stays fixed and fast).
FUZZ = settings(
    max_examples=int(os.environ.get("QSID_FUZZ_EXAMPLES", "60")),
    deadline=None,
    derandomize=os.environ.get("QSID_FUZZ_RANDOM") != "1",
    database=None,
    suppress_health_check=list(HealthCheck),
)

finite = st.floats(-1e3, 1e3, allow_nan=False)
weird_number = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(-(10**6), 10**6),
    st.sampled_from([10**400, -(10**400), 2**1024, 0.0, -0.0, 5e-324, 1e-300, 1e11, 1e13, 1e300, -1e308]),
)
junk = st.one_of(
    st.booleans(),
    st.none(),
    st.text(max_size=5),
    st.dictionaries(st.text(max_size=2), finite, max_size=2),
    st.dates(),
    st.just(nested(300)),
    st.just([]),
    st.complex_numbers(max_magnitude=2),
    st.just(np.array([1.0, 2.0])),
    st.just(np.float64("nan")),
    st.just(np.int64(3)),
)
number = st.one_of(finite, finite, finite, weird_number)
value = st.one_of(number, junk)


def rows(n, m, elements=number):
    return st.lists(st.lists(elements, min_size=m, max_size=m), min_size=n, max_size=n)


@st.composite
def mostly_valid(draw, valid: dict, bad=value):
    """Keyword arguments drawn from ``valid``; half the time one of them is replaced by a bad value."""
    kw = {k: draw(s) for k, s in valid.items()}
    if draw(st.booleans()):
        k = draw(st.sampled_from(sorted(kw)))
        kw[k] = draw(st.one_of(bad, st.lists(bad, max_size=3), rows(2, 2, bad)))
    return kw


@st.composite
def system_kwargs(draw, elements=st.one_of(finite, st.sampled_from([0.0, 1e-12, 1e12, -1e12]))):
    n, m = draw(st.integers(1, 3)), draw(st.integers(1, 2))
    diag = st.lists(st.floats(0.01, 100), min_size=n, max_size=n)
    return draw(
        mostly_valid(
            {
                "A": rows(n, n, elements),
                "B": rows(n, m, elements),
                "x0": st.one_of(st.none(), st.lists(finite, min_size=n, max_size=n)),
                "Q": st.one_of(st.none(), diag),
                "R": st.one_of(st.none(), st.lists(st.floats(0.01, 100), min_size=m, max_size=m)),
                "dt": st.one_of(st.just(1.0), st.floats(1e-9, 1e6)),
                "name": st.text(max_size=300),
            }
        )
    )


def _finite(*arrs) -> bool:
    return all(np.all(np.isfinite(np.asarray(a, dtype=float))) for a in arrs)


def _call(fn, *a, **k):
    """Run ``fn``: a QsidError is fine (returns None); any other exception fails the test (see support.fuzz_call)."""
    return fuzz_call(getattr(fn, "__name__", type(fn).__name__), fn, *a, **k)


@FUZZ
@given(kw=system_kwargs())
@pytest.mark.slow
def test_fuzz_ltisystem(kw):
    s = _call(LTISystem, kw.pop("name"), kw.pop("A"), kw.pop("B"), **kw)
    if s is not None:
        assert _finite(s.A, s.B, s.x0, s.Q, s.R, s.dt) and s.dt > 0
        json.dumps(s.to_dict(), allow_nan=False)


@FUZZ
@given(
    kw=system_kwargs(elements=st.one_of(finite, finite, st.integers(-9, 9), st.sampled_from([10**400, 0.0]))),
    fmt=st.sampled_from(["json", "json", "toml", "toml", "garbage"]),
    extra=st.one_of(st.none(), st.none(), st.none(), value),
    date=st.booleans(),
)
def test_fuzz_load_system(kw, fmt, extra, date):
    doc = {k: v for k, v in kw.items() if v is not None}
    if extra is not None:
        doc["extra" if date else "Q"] = extra
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / f"s.{fmt}"
        if fmt == "toml":
            text = "\n".join(
                f"{k} = {v.isoformat() if isinstance(v, datetime.date) else json.dumps(v, default=str)}"
                for k, v in doc.items()
            )
        else:
            try:
                text = json.dumps(doc, default=str)
            except (ValueError, TypeError):
                text = "{"
        p.write_text(text, encoding="utf-8")
        s = _call(load_system, p)
        if s is not None:
            assert _finite(s.A, s.B, s.x0, s.Q, s.R, s.dt)
        _call(get_system, str(p))


@FUZZ
@given(
    spec=st.one_of(
        st.text(alphabet="0123456789:,- ", max_size=40),
        value,
        st.lists(value, max_size=4),
        st.lists(st.integers(-3, 40), max_size=6),
        st.builds(range, st.integers(-5, 40), st.integers(-5, 40)),
    )
)
def test_fuzz_parse_bits(spec):
    out = _call(parse_bits, spec)
    if out is not None:
        assert out and all(isinstance(b, int) and 1 <= b <= 32 for b in out)


pair = st.tuples(st.one_of(finite, weird_number), st.one_of(finite, weird_number))


@FUZZ
@given(
    kw=mostly_valid(
        {
            "dither": st.sampled_from(["subtractive", "none"]),
            "range_mode": st.sampled_from(["per-channel", "shared", "fixed"]),
            "guard": st.booleans(),
            "fixed_range": st.one_of(st.none(), pair, st.lists(pair, min_size=1, max_size=4)),
        }
    )
)
def test_fuzz_quantizer_spec(kw):
    q = _call(QuantizerSpec, **kw)
    if q is not None and q.fixed_range is not None:
        fr = np.asarray(q.fixed_range)
        assert _finite(fr, fr[:, 1] - fr[:, 0]) and np.all(fr[:, 1] > fr[:, 0])


@FUZZ
@given(
    kw=mostly_valid(
        {
            "x": st.lists(st.one_of(finite, finite, finite, weird_number), min_size=1, max_size=6),
            "lo": st.one_of(st.floats(-1e3, 0.0), weird_number),
            "hi": st.one_of(st.floats(1e-3, 1e3), weird_number),
            "bits": st.integers(1, 32),
            "dither": st.sampled_from(["subtractive", "none"]),
            "guard": st.booleans(),
            "seed": st.integers(0, 3),
        }
    )
)
def test_fuzz_quantize(kw):
    seed = kw.pop("seed")
    rng = np.random.default_rng(seed) if isinstance(seed, int) and not isinstance(seed, bool) and seed >= 0 else seed
    x, lo, hi, bits = kw.pop("x"), kw.pop("lo"), kw.pop("hi"), kw.pop("bits")
    q = _call(quantize, x, lo, hi, bits, rng=rng, **kw)
    if q is not None:
        assert _finite(q.values, q.eps) and np.all(q.eps > 0) and q.values.shape == np.shape(x)


vec3 = st.one_of(st.none(), st.floats(1e-6, 1e12), st.lists(st.floats(1e-6, 1e12), min_size=1, max_size=3))
mpc_kwargs = mostly_valid(
    {
        "horizon": st.integers(1, 200),
        "steps": st.integers(1, 10000),
        "u_max": st.floats(1e-6, 1e12),
        "x_max": vec3,
        "xf_max": vec3,
        "Q": vec3,
        "R": vec3,
        "Qf": vec3,
        "x0": st.one_of(st.none(), st.lists(finite, min_size=1, max_size=3)),
        "x_ref": st.one_of(st.none(), st.lists(finite, min_size=1, max_size=3)),
        "eps": st.floats(1e-12, 1e-2),
        "max_iter": st.integers(1, 10**6),
    }
)


@FUZZ
@given(kw=mpc_kwargs)
def test_fuzz_mpc_config(kw):
    c = _call(MPCConfig, **kw)
    if c is not None:
        for v in (c.u_max, c.x_max, c.xf_max, c.Q, c.R, c.Qf, c.x0, c.x_ref):
            assert v is None or (len(v) > 0 and _finite(v))


@FUZZ
@given(
    kw=mostly_valid(
        {
            "system": st.sampled_from(["dc-motor", "boeing747", "nope", "/tmp", "x.toml", "a" * 300]),
            "bits": st.one_of(st.text(alphabet="0123456789:,", max_size=8), st.lists(st.integers(1, 32), min_size=1)),
            "realizations": st.integers(1, 10000),
            "trajectories": st.integers(1, 100_000),
            "steps": st.integers(1, 10**6),
            "data_seed": st.integers(0, 10**30),
            "dither_seed": st.integers(0, 5),
            "quantizer": st.just(QuantizerSpec()),
            "estimator": st.sampled_from(["ls", "bcls"]),
            "mpc": st.one_of(st.none(), st.just(MPCConfig())),
            "theta": st.floats(1e-300, 0.999),
            "rho": st.one_of(st.none(), st.floats(1e-300, 1e12)),
        }
    )
)
def test_fuzz_sweep_config(kw):
    c = _call(SweepConfig, **kw)
    if c is not None:
        assert c.bits and (c.rho is None or 0 < c.rho <= 1e12) and 0 < c.theta < 1


def _check_sweep(res) -> None:
    """Every reported number is finite unless flagged as a failure (with a note), and to_dict is strict JSON."""
    for b in res.bits:
        ident = res.identification[b]
        ok = ~ident.failed
        assert _finite(ident.eps) and np.all(ident.eps > 0)
        assert _finite(ident.A_hat[ok], ident.B_hat[ok], ident.err_A[ok], ident.err_B[ok])
        assert np.all(np.isnan(ident.A_hat[~ok])) and (ok.all() or ident.notes)
        th = res.theory[b]
        assert _finite(th.err_A, th.err_B)
        assert math.isfinite(th.delta) or th.bound_note, f"delta = {th.delta} without a note"
        lp = res.loops.get(b)
        if lp is not None:
            good = ~lp.failed
            assert _finite(lp.cost[good], lp.states[good], lp.inputs[good])
            assert all(msg for f, msg in zip(lp.failure, lp.messages) if f)
    json.dumps(res.to_dict(), allow_nan=False)


small_entry = st.one_of(
    st.floats(-1.2, 1.2, allow_nan=False),
    st.floats(-1.2, 1.2, allow_nan=False),
    st.sampled_from([0.0, 1e-300, 1e-8, 3.0, 1e6, -1e11]),
)


@st.composite
def tiny_system(draw):
    n = draw(st.integers(1, 3))
    m = draw(st.integers(1, 2))
    return (draw(rows(n, n, small_entry)), draw(rows(n, m, small_entry)))


@FUZZ
@given(
    sysAB=tiny_system(),
    bits=st.lists(st.integers(1, 32), min_size=1, max_size=3),
    trajectories=st.integers(1, 3),
    steps=st.integers(1, 25),
    realizations=st.integers(1, 3),
    dither=st.sampled_from(["subtractive", "none"]),
    range_mode=st.sampled_from(["per-channel", "shared", "fixed"]),
    guard=st.booleans(),
    fixed=st.tuples(st.sampled_from([-1e300, -10.0, -1.0, 0.0, 1e-300]), st.sampled_from([1e-290, 1e-3, 1.0, 1e300])),
    estimator=st.sampled_from(["ls", "bcls"]),
    mpc=st.one_of(
        st.none(),
        st.builds(
            MPCConfig,
            horizon=st.integers(1, 4),
            steps=st.integers(1, 6),
            u_max=st.sampled_from([1e-6, 0.5, 1.0, 1e6]),
            x_max=st.sampled_from([None, 1e-3, 2.0]),
            Q=st.sampled_from([None, 0.0, 1e-12, 1e12]),
        ),
    ),
    rho=st.sampled_from([None, 1e-12, 1.0, 1e12]),
    theta=st.sampled_from([1e-300, 0.5, 0.999]),
)
def test_fuzz_run_sweep_tiny(
    sysAB, bits, trajectories, steps, realizations, dither, range_mode, guard, fixed, estimator, mpc, rho, theta
):
    A, B = sysAB
    s = _call(LTISystem, "fuzz", A, B)
    if s is None:
        return
    steps = max(steps, -(-(s.n + s.m) // trajectories))  # enough samples for n + m unknowns per row
    q = _call(
        QuantizerSpec,
        dither=dither,
        range_mode=range_mode,
        guard=guard,
        fixed_range=fixed if range_mode == "fixed" else None,
    )
    if q is None:
        return
    cfg = _call(
        SweepConfig,
        system=s,
        bits=tuple(bits),
        realizations=realizations,
        trajectories=trajectories,
        steps=steps,
        quantizer=q,
        estimator=estimator,
        mpc=mpc,
        rho=rho,
        theta=theta,
    )
    if cfg is None:
        return
    res = _call(run_sweep, cfg)
    if res is not None:
        _check_sweep(res)


wide = st.one_of(st.floats(-1e3, 1e3), st.sampled_from([0.0, 1e-300, -1e-300, 1e12, -1e12, 1e150, 1e300]))


@FUZZ
@given(
    P=rows(2, 2, wide),
    q=st.lists(st.one_of(st.floats(1e-300, 1e12), st.just(0.0)), min_size=2, max_size=2),
    r=st.floats(1e-300, 1e12),
    dA=rows(2, 2, wide),
    dB=rows(2, 1, wide),
    theta=st.one_of(st.floats(5e-324, 0.999999), st.sampled_from([0.0, 1.0, 5e-324])),
    rho=st.one_of(st.none(), st.floats(5e-324, 1e12), st.just(1e300)),
    x0=st.one_of(st.none(), st.lists(wide, min_size=2, max_size=2)),
)
def test_fuzz_ultimate_bound(P, q, r, dA, dB, theta, rho, x0):
    P = np.asarray(P)
    ub = _call(
        ultimate_bound,
        (P + P.T) / 2,
        np.diag(q),
        np.array([[r]]),
        np.asarray(dA),
        np.asarray(dB),
        theta=theta,
        rho=rho,
        x0=None if x0 is None else np.asarray(x0),
    )
    if ub is not None:
        assert math.isfinite(ub.delta) or ub.note, f"delta = {ub.delta} without a note"
        assert not math.isnan(ub.delta) and ub.delta >= 0


def test_non_finite_entries_are_located_as_a_person_counts_and_inf_is_explained():
    from qsid_core.validate import as_float_array

    with pytest.raises(ValueError, match=r"x0 must contain only finite numbers .*entry 2 is inf \(a number beyond"):
        as_float_array("x0", [1.0, float("inf")], ndim_max=1)
    with pytest.raises(ValueError, match=r"row 2, column 1 is nan$"):
        as_float_array("A", [[1.0, 2.0], [float("nan"), 0.0]], ndim_max=2)
