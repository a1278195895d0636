"""Every field of every engine config is a setting of the table (app/settings/settings.toml) or declared internal
there, with its reason: a new config field without a setting fails here, whatever else it passes."""

from __future__ import annotations

import dataclasses

import pytest

import qsid_core
import qsid_core.studies
from app.settings import SETTINGS
from app.settings.schema import INTERNAL
from qsid_core import DataLengthConfig, MPCConfig, QuantizerSpec, SweepConfig
from qsid_core.studies import KOOPMAN_MPC_UNUSED, BudgetConfig, KoopmanConfig

#: The engine's configs by the settings table's name of them (the Setting attribute holding a path into each).
CONFIGS: dict[str, type] = {
    "sweep": SweepConfig,
    "nonlinear": KoopmanConfig,
    "datalength": DataLengthConfig,
    "budget": BudgetConfig,
}
#: The configs nested in those, by field name (each of their fields is reached through its parent's path).
NESTED: dict[str, type] = {"quantizer": QuantizerSpec, "mpc": MPCConfig}
#: The Setting attribute holding each config's paths.
COLUMN = {"sweep": "engine", "nonlinear": "nonlinear", "datalength": "datalength", "budget": "budget"}


def _paths(cls: type, prefix: str = "") -> list[str]:
    """Dotted paths of every field of ``cls``; a nested config is replaced by its fields."""
    out: list[str] = []
    for f in dataclasses.fields(cls):
        if not prefix and f.name in NESTED:
            out += _paths(NESTED[f.name], f.name + ".")
        else:
            out.append(prefix + f.name)
    return out


def _declared(config: str) -> set[str]:
    return {p for s in SETTINGS if (p := getattr(s, COLUMN[config])) is not None}


def _uncovered(config: str, declared: set[str], internal: dict[str, str]) -> list[str]:
    return [p for p in _paths(CONFIGS[config]) if p not in declared and f"{config}.{p}" not in internal]


@pytest.mark.parametrize("config", CONFIGS)
def test_every_field_of_every_engine_config_is_a_setting_or_declared_internal(config):
    missing = _uncovered(config, _declared(config), INTERNAL)
    assert not missing, (
        f"{CONFIGS[config].__name__} field(s) {missing} have no setting: write its table in "
        f'app/settings/settings.toml with {COLUMN[config]} = "PATH", or list "{config}.PATH" under [internal] '
        "with the reason no person sets it"
    )


def test_the_test_sees_a_field_without_a_setting():
    """Taking one setting's path away (or one internal entry) is caught, for each config."""
    for config in CONFIGS:
        declared = _declared(config)
        some = sorted(declared & set(_paths(CONFIGS[config])))[0]
        before = set(_uncovered(config, declared, INTERNAL))
        assert set(_uncovered(config, declared - {some}, INTERNAL)) - before == {some}
    dropped = dict(INTERNAL)
    del dropped["sweep.mpc.solver"]
    assert "mpc.solver" in _uncovered("sweep", _declared("sweep"), dropped)


def test_every_internal_entry_is_a_real_field_no_setting_sets_with_a_reason():
    for key, reason in INTERNAL.items():
        config, _, path = key.partition(".")
        assert config in CONFIGS and path in _paths(CONFIGS[config]), key
        assert path not in _declared(config), f"{key} is a setting's path and internal at once"
        assert len(reason.split()) >= 4, f"{key}: say why no person sets it"


def test_every_path_of_the_table_is_a_real_field():
    for config in CONFIGS:
        assert _declared(config) <= set(_paths(CONFIGS[config])), _declared(config) - set(_paths(CONFIGS[config]))


def test_the_koopman_mpcs_refused_fields_are_internal_there():
    assert {f"nonlinear.mpc.{k}" for k in KOOPMAN_MPC_UNUSED} <= set(INTERNAL)


def test_every_engine_config_is_checked_here():
    """A config class of the engine's public API (a dataclass named *Config or *Spec) is one of those above."""
    found = {
        obj
        for mod in (qsid_core, qsid_core.studies)
        for name in mod.__all__
        if name.endswith(("Config", "Spec"))
        for obj in [getattr(mod, name)]
        if isinstance(obj, type) and dataclasses.is_dataclass(obj)
    }
    assert found == set(CONFIGS.values()) | set(NESTED.values()), found
