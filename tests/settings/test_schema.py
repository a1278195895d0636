"""The settings table (app/settings/settings.toml): each setting declared once, everything else generated."""

from __future__ import annotations

import dataclasses

import pytest

from app.settings import BY_NAME, SETTINGS, resolve, value_default
from app.settings.check import InputError, check_setting
from qsid_core import MPCConfig, SweepConfig
from qsid_core.studies.cache_keys import config_paths


def test_every_engine_path_is_a_real_config_field_and_defaults_are_the_engines():
    paths = set(config_paths())
    for s in SETTINGS:
        if s.engine is not None:
            assert s.engine in paths, (s.name, s.engine)
    sweep, mpc = SweepConfig(), MPCConfig()
    assert resolve(BY_NAME["dither_seed"].default) == sweep.dither_seed
    assert resolve(BY_NAME["loop_seed"].default) == mpc.loop_seed
    assert resolve(BY_NAME["guard"].default) is sweep.quantizer.guard
    assert value_default(BY_NAME["realizations"]) == 20 != sweep.realizations  # the panel's interactive size


def test_the_dashboards_values_and_panel_are_the_tables():
    from app.dashboard.controls import CONTROLS
    from app.settings.values import DISPLAY_ONLY, Values

    fields = [f.name for f in dataclasses.fields(Values)]
    assert fields == [s.name for s in SETTINGS if s.values]
    assert [c.name for c in CONTROLS] == [s.name for s in SETTINGS if s.control]
    assert set(DISPLAY_ONLY) == {s.name for s in SETTINGS if s.display}
    assert all(getattr(Values(), s.name) == value_default(s) for s in SETTINGS if s.values)


def test_every_generated_flag_parses_to_the_engines_default():
    from app.cli import build_parser

    args = build_parser().parse_args(["sweep"])
    for s in SETTINGS:
        if s.flag is not None and s.cli_default is ...:
            assert getattr(args, s.dest) == resolve(s.default), s.name


def test_stages_a_setting_invalidates_come_from_the_engines_cache_keys():
    assert "data" in BY_NAME["data_seed"].stages() and "mom" in BY_NAME["data_seed"].stages()
    assert "data" not in BY_NAME["dither_seed"].stages() and "mom" in BY_NAME["dither_seed"].stages()
    assert BY_NAME["loop_seed"].stages() == ("loops", "true-loop", "true-loop-fed")
    assert BY_NAME["bits"].stages() == () and BY_NAME["presenter"].stages() == ()


@pytest.mark.parametrize(
    "name,value",
    [("bits", 3.7), ("bits", "5"), ("bits", True), ("guard", "false"), ("guard", 1), ("guard", [0]), ("theta", "0.5")],
)
def test_values_are_checked_by_type_before_any_conversion(name, value):
    with pytest.raises(InputError, match=BY_NAME[name].label):
        check_setting(BY_NAME[name], value)


def test_a_whole_float_is_an_integer_and_a_list_of_numbers_a_tuple():
    assert check_setting(BY_NAME["bits"], 4.0) == 4 and type(check_setting(BY_NAME["bits"], 4.0)) is int
    assert check_setting(BY_NAME["log_q"], [0, 1.5]) == (0.0, 1.5)


def test_the_state_amplitude_reaches_the_data_and_every_front_end():
    """The setting added with one table in settings.toml (issue 30 item 7)."""
    import numpy as np

    from app.cli import build_parser
    from app.cli.runner import config, system_from_args
    from app.settings.command import sweep_argv
    from qsid_core import ConfigError, get_system, simulate

    system = get_system("dc-motor")
    one, two = simulate(system, 4, 6, 3), simulate(system, 4, 6, 3, state_amplitude=2.0)
    np.testing.assert_allclose(two.states[:, 0], 2.0 * one.states[:, 0])  # the same draws, scaled
    np.testing.assert_array_equal(two.inputs, one.inputs)
    assert np.abs(two.states[:, 0]).max() > 1.0
    with pytest.raises(ConfigError, match="state amplitude"):
        SweepConfig(state_amplitude=0.0)
    args = build_parser().parse_args(["sweep", "--state-amplitude", "2.5"])
    cfg = config(args, system_from_args(args), mpc=True)
    assert cfg.state_amplitude == 2.5 and "--state-amplitude=2.5" in sweep_argv(cfg)
    assert SweepConfig.from_dict(cfg.to_dict()).state_amplitude == 2.5
    assert BY_NAME["state_amplitude"].stages()[0] == "data"


def test_no_front_end_reaches_into_the_other():
    """The dashboard and the front-end-neutral packages it draws from (the exports module writes the command line
    with the schema's writer) import none of the CLI's modules."""
    import ast
    from pathlib import Path

    import app.dashboard

    app_dir = Path(app.dashboard.__file__).parent.parent
    for path in [p for pkg in ("dashboard", "frames", "lessons", "settings") for p in (app_dir / pkg).glob("*.py")]:
        tree = ast.parse(path.read_text(encoding="utf-8"))
        names = [n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
        names += [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
        assert not [m for m in names if m == "app.cli" or m.startswith("app.cli.")], path.name


def test_every_nonlinear_path_is_a_koopman_config_field_and_every_field_a_user_sets_is_declared():
    """The nonlinear settings are declared once: each ``nonlinear`` path is a real field of KoopmanConfig, and
    every KoopmanConfig field is set by a setting, except the MPC's fields the Koopman loops refuse."""
    from app.settings.schema import nonlinear_default, nonlinear_settings
    from qsid_core.studies import KOOPMAN_MPC_UNUSED, KoopmanConfig

    paths = set(config_paths(KoopmanConfig))
    declared = {s.nonlinear for s in nonlinear_settings()}
    assert declared <= paths, declared - paths
    unused = {f"mpc.{k}" for k in KOOPMAN_MPC_UNUSED} | {"mpc.verify_steps", "mpc.eps", "mpc.max_iter", "mpc.solver"}
    containers = {"quantizer", "mpc"}
    missing = sorted(p for p in paths - declared - unused - containers if p != "bits")  # bits: --bits, by hand
    assert not missing, f"KoopmanConfig field(s) {missing} have no setting (settings.toml 'nonlinear = ...')"
    base = KoopmanConfig()
    assert nonlinear_default(BY_NAME["lifting"]) == base.lifting == "poly:3"
    assert nonlinear_default(BY_NAME["trajectories"]) == base.trajectories != resolve(BY_NAME["trajectories"].default)
    assert nonlinear_default(BY_NAME["horizon"]) == base.mpc.horizon
    assert nonlinear_default(BY_NAME["converged_radius"]) == base.radius
    assert value_default(BY_NAME["sane_box"]) == base.plant().box and nonlinear_default(BY_NAME["sane_box"]) is None
    assert BY_NAME["noise"].nonlinear is None and BY_NAME["tracking"].nonlinear is None  # refused by nonlinear runs


def test_the_system_choices_list_every_preset_linear_and_nonlinear():
    from qsid_core import PRESETS
    from qsid_core.plant import NONLINEAR_PRESETS

    choices = resolve(BY_NAME["system"].choices)
    assert choices == (*PRESETS, *NONLINEAR_PRESETS) and "van-der-pol" in choices


def test_nonlinear_stages_come_from_the_koopman_keys():
    assert BY_NAME["lifting"].stages() == ()  # no linear stage holds it
    assert "data" not in BY_NAME["lifting"].stages(nonlinear=True)
    assert "models" in BY_NAME["lifting"].stages(nonlinear=True)
    assert BY_NAME["converged_radius"].stages(nonlinear=True) == ("reference-loop", "loops")
    assert BY_NAME["sane_box"].stages(nonlinear=True)[0] == "data"
    assert BY_NAME["dither_seed"].stages(nonlinear=True) == ("moments", "models", "loops")


def test_the_nonlinear_flags_are_generated_with_the_nonlinear_defaults_in_their_help():
    from app.cli import build_parser

    parser = build_parser()
    args = parser.parse_args(["sweep", "--lifting", "rbf:12:gauss", "--sane-box", "20", "--converged-radius", "0.05"])
    assert (args.lifting, args.sane_box, args.converged_radius) == ("rbf:12:gauss", 20.0, 0.05)
    sweep = parser._subparsers._group_actions[0].choices["sweep"]  # the sweep command's parser
    helps = {a.option_strings[0]: a.help for a in sweep._actions if a.option_strings}
    assert "nonlinear plants: 2000" in helps["--trajectories"]
    assert "(default: poly:3)" in helps["--lifting"]
