"""Panel values -> engine configuration (app.settings.values): defaults, every control, plain-words errors."""

from __future__ import annotations

import numpy as np
import pytest

from app.dashboard.controls import CONTROLS
from app.dashboard.viewpanel import VIEW_FIELDS
from app.figures.phase_scene import axes_indices, axes_options
from app.settings.config import estimators, mpc_config, sweep_config
from app.settings.values import (
    ALL_BITS,
    IDENT_CHOICES,
    INTERACTIVE,
    PAPER_SCALE,
    InputError,
    Values,
    format_weights,
    log_from_weights,
    matrix_text,
    resolve_system,
    weights_from_log,
)
from qsid_core import MPCConfig, SweepConfig
from qsid_core.errors import QsidError
from qsid_core.identification.identify import ESTIMATORS
from qsid_core.quantization.quantize import DITHERS, RANGE_MODES


def test_defaults_map_to_the_interactive_sweep():
    v = Values()
    sysm = resolve_system(v).system
    cfg = sweep_config(v, sysm)
    assert cfg.bits == ALL_BITS == tuple(range(1, 17))
    assert (cfg.trajectories, cfg.steps, cfg.realizations) == (50, 200, 20)
    assert INTERACTIVE == {"trajectories": 50, "steps": 200, "realizations": 20}
    assert PAPER_SCALE == {"trajectories": 200, "steps": 1000, "realizations": 50}
    assert cfg.estimator == "ls" and cfg.theta == 0.5 and cfg.rho is None
    assert cfg.quantizer.dither == "subtractive" and cfg.quantizer.range_mode == "per-channel"
    assert cfg.mpc.horizon == 10 and cfg.mpc.steps == 50 and cfg.mpc.u_max == (1.0,)
    assert cfg.mpc.Q is None and cfg.mpc.R is None and cfg.mpc.x0 is None  # the system's defaults


def test_every_control_reaches_the_config():
    v = Values(
        system="boeing747",
        bits=7,
        dither="none",
        range_mode="shared",
        guard=True,
        realizations=3,
        dither_seed=9,
        trajectories=12,
        steps=40,
        data_seed=5,
        identification="BCLS",
        horizon=7,
        log_q=(0.0, -1.0, 1.0, 0.5),
        log_r=(0.3, -0.3),
        u_max=2.5,
        x0="1, 0.5, 0, 0",
        mpc_steps=30,
        theta=0.3,
        rho_auto=False,
        rho=2.0,
    )
    sysm = resolve_system(v).system
    cfg = sweep_config(v, sysm)
    assert sysm.name == "boeing747"
    assert (cfg.realizations, cfg.dither_seed, cfg.trajectories, cfg.steps, cfg.data_seed) == (3, 9, 12, 40, 5)
    assert cfg.quantizer.dither == "none" and cfg.quantizer.range_mode == "shared" and cfg.quantizer.guard
    assert cfg.estimator == "bcls" and cfg.theta == 0.3 and cfg.rho == 2.0
    m = cfg.mpc
    assert (m.horizon, m.steps, m.u_max, m.x0) == (7, 30, (2.5,), (1.0, 0.5, 0.0, 0.0))
    assert m.Q == (1.0, 0.1, 10.0, 3.162) and m.R == (1.995, 0.5012)


def test_log_sliders_hold_log10_of_the_weight():
    assert weights_from_log([0, -1, 1, 0.5]) == (1.0, 0.1, 10.0, 3.162)
    assert log_from_weights([1.0, 0.1, 100.0]) == (0.0, -1.0, 2.0)
    assert log_from_weights([0.0, 1e9]) == (-3.0, 3.0)  # zero and huge weights land at the slider ends
    for w in (0.01, 0.5, 1.0, 7.0):
        assert weights_from_log(log_from_weights([w]))[0] == pytest.approx(w, rel=0.02)
    assert format_weights("Q", (1.0, 0.1)) == "Q = diag(1, 0.1)"
    sysm = resolve_system(Values()).system
    assert mpc_config(Values(log_q=(0.0, 0.0, 0.0)), sysm).Q == (1.0, 1.0, 1.0)
    assert mpc_config(Values(log_q=(0.0, 0.0)), sysm).Q is None  # wrong length (another system's): default


def test_estimator_choices():
    assert estimators("LS") == ("ls",) and estimators("BCLS") == ("bcls",)
    assert estimators("LS + BCLS") == ("ls", "bcls")
    with pytest.raises(InputError, match="identification must be one of"):
        estimators("ML")


def test_custom_system_from_typed_matrices():
    v = Values(system="custom", a_text="0.9 0.2\n0 0.8", b_text="0; 1")
    ch = resolve_system(v)
    assert ch.system.n == 2 and ch.system.m == 1 and ch.notes == ()
    np.testing.assert_allclose(ch.system.A, [[0.9, 0.2], [0.0, 0.8]])
    cfg = sweep_config(v, ch.system)
    assert cfg.mpc.Q is None
    assert axes_indices("", ch.system.state_names) == (0, 1, None)
    # the boxes show a preset the same way they are typed
    assert matrix_text(np.array([[1.0, 0.099], [0.0, -2.5]])) == "1 0.099\n0 -2.5"


@pytest.mark.parametrize(
    "a, b, words",
    [
        ("1 2\n3 x", "1; 0", "A row 2: '3 x' has an entry that is not a number"),
        ("1 2\n3", "1; 0", "A: rows have different lengths"),
        ("", "1", "A is empty"),
        ("1 2 3\n4 5 6", "1; 0", "A must be square"),
        ("0.9 0.2\n0 0.8", "1; 0; 2", "B must have one row per state (2 rows, like A); it has 3"),
        ("0.9 0.2\n0 0.8", "1 0", "did you type B transposed?"),
        ("0.9 0.2\n0 0.8", "[[1], [0]", "B: not valid JSON"),
        ("0.9 inf\n0 0.8", "1; 0", "only finite numbers"),
    ],
)
def test_bad_custom_matrices_say_what_is_wrong(a, b, words):
    with pytest.raises(InputError) as exc:
        resolve_system(Values(system="custom", a_text=a, b_text=b))
    msg = str(exc.value)
    assert msg.startswith("Custom system: ")
    assert words in msg
    assert isinstance(exc.value, QsidError) and isinstance(exc.value, ValueError)


def test_uncontrollable_custom_system_gives_a_note_not_an_error():
    ch = resolve_system(Values(system="custom", a_text="0.5 0\n0 0.5", b_text="1; 0"))
    assert len(ch.notes) == 1 and "not controllable" in ch.notes[0] and "MPC may fail" in ch.notes[0]


@pytest.mark.parametrize(
    "field, value, words",
    [
        ("x0", "1, 2", "x0 needs 3 numbers (one per state: angle, speed, current); got 2"),
        ("x0", "1, a, 0", "not a number"),
        ("fixed_range", "2, 1", "every range needs lo < hi"),
        ("fixed_range", "1 2 3", "fixed range: give one 'lo, hi' pair"),
        ("u_max", -1.0, "u_max must be positive"),
        ("bits", 17, "word length b must be between 1 and 16"),
        ("rho", -2.0, "rho must be a positive number"),
        ("theta", 1.0, "theta must be in (0, 1)"),
    ],
)
def test_bad_panel_values_raise_plain_words(field, value, words):
    kw = {field: value}
    if field == "fixed_range":
        kw["range_mode"] = "fixed"
    if field == "rho":
        kw["rho_auto"] = False
    v = Values(**kw)
    with pytest.raises(InputError) as exc:
        sweep_config(v, resolve_system(v).system)
    assert words in str(exc.value)


def test_fixed_range_one_pair_or_one_per_channel():
    v = Values(range_mode="fixed", fixed_range="-30, 30")
    sysm = resolve_system(v).system
    assert sweep_config(v, sysm).quantizer.fixed_range == ((-30.0, 30.0),)
    v = v.replace(fixed_range="-30 30; -5 5; -1 1; -1 1; -1 1")
    assert len(sweep_config(v, sysm).quantizer.fixed_range) == 5


def test_axes_choices_for_four_states():
    names = ("u", "w", "q", "theta")
    opts = axes_options(names)
    assert opts == ["u, w, q", "u, w, theta", "u, q, theta", "w, q, theta"]
    assert axes_indices("u, q, theta", names) == (0, 2, 3)
    assert axes_indices("nonsense", names) == (0, 1, 2)
    assert axes_options(("a", "b", "c")) == ["a, b, c"]


def test_defaults_and_choices_are_the_engines():
    """One source of truth: the panel's defaults, choices and b range come from the engine."""
    eng, mpc, v = SweepConfig(), MPCConfig(), Values()
    assert ALL_BITS == eng.bits
    assert PAPER_SCALE == {"trajectories": eng.trajectories, "steps": eng.steps, "realizations": eng.realizations}
    assert (v.horizon, v.mpc_steps, (v.u_max,), v.theta) == (mpc.horizon, mpc.steps, mpc.u_max, eng.theta)
    assert (v.data_seed, v.dither_seed) == (eng.data_seed, eng.dither_seed)
    spec = {c.name: c for c in CONTROLS}
    assert (spec["bits"].lo, spec["bits"].hi) == (eng.bits[0], eng.bits[-1])
    assert spec["dither"].choices == DITHERS and spec["range_mode"].choices == RANGE_MODES
    assert IDENT_CHOICES[spec["identification"].choices[-1]] == ESTIMATORS


def test_every_values_field_has_one_control():
    names = [c.name for c in CONTROLS]
    assert len(names) == len(set(names))
    fields = set(Values.__dataclass_fields__) - {"log_q", "log_r"}  # the weight sliders follow the system
    fields -= set(VIEW_FIELDS)  # the views' own inputs sit next to the views (plots panel)
    assert set(names) == fields


def test_same_results_ignores_only_display_settings():
    from app.settings.values import DISPLAY_ONLY

    base = Values()
    shown = base.replace(bits=base.bits + 1, show_bound=not base.show_bound, presenter=not base.presenter)
    assert base.same_results(shown) and shown.same_results(base)
    assert not base.same_results(base.replace(data_seed=base.data_seed + 1))
    assert not base.same_results(base.replace(system="boeing-747"))
    assert "bits" in DISPLAY_ONLY and "data_seed" not in DISPLAY_ONLY


def test_the_data_length_study_is_the_tabs_sweep_at_its_b_with_the_engines_key():
    """Every panel setting the study shares with the sweep reaches it (amplitudes, noise, word length per channel,
    seeds, quantizer), and its cache key is the engine's: a change of any of them is another study."""
    from app.frames.datalength import MAX_REALIZATIONS, _key, datalength_config
    from app.settings.values import Values

    base = Values(system="dc-motor", bits=6)
    changed = dict(
        input_amplitude=0.5,
        state_amplitude=2.0,
        noise="0.01",
        noise_known=True,
        input_bits="exact",
        state_bits="b, 5, b",
        data_seed=4,
        dither_seed=5,
        guard=False,
    )
    cfg = datalength_config(base)
    assert cfg.bits == 6 and cfg.realizations == min(base.realizations, MAX_REALIZATIONS)
    new = datalength_config(base.replace(**changed))
    assert (new.input_amplitude, new.state_amplitude, new.noise, new.noise_known) == (0.5, 2.0, (0.01,), True)
    assert (new.input_bits, new.state_bits, new.data_seed, new.dither_seed) == ("exact", ("b", 5, "b"), 4, 5)
    assert new.quantizer.guard is False
    for name, value in changed.items():
        assert _key(datalength_config(base.replace(**{name: value}))) != _key(cfg), name
    assert _key(datalength_config(Values(system="dc-motor", bits=6))) == _key(cfg)
