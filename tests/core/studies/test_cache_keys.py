"""Cache keys are generated from the engine configs' fields: none can be forgotten."""

from __future__ import annotations

import dataclasses

import pytest

from qsid_core import MPCConfig, QuantizerSpec, SweepConfig, get_system
from qsid_core.studies.cache_keys import KEY_PARTS, NOT_IN_KEYS, STAGE_GROUPS, config_paths, stage_key


def _covered(path: str) -> bool:
    parts = [p for group in KEY_PARTS.values() for p in group]
    return path in NOT_IN_KEYS or any(path == p or path.startswith(p + ".") for p in parts)


def test_every_field_of_every_engine_config_is_in_a_key_or_declared_keyless():
    paths = config_paths()
    assert "quantizer.dither" in paths and "mpc.loop_seed" in paths and "data_seed" in paths
    # a nested config is covered when each of its fields is
    containers = {"quantizer", "mpc"}
    missing = [p for p in paths if p not in containers and not _covered(p)]
    assert not missing, f"config field(s) {missing} are in no cache key (cache_keys.KEY_PARTS) nor in NOT_IN_KEYS"


def test_every_key_part_names_a_real_field():
    paths = set(config_paths())
    assert {p for group in KEY_PARTS.values() for p in group} <= paths
    assert set(NOT_IN_KEYS) <= paths
    assert {g for groups in STAGE_GROUPS.values() for g in groups} <= set(KEY_PARTS)


BASE = SweepConfig(bits=(2, 3), realizations=2, trajectories=3, steps=10)
# one new value per field; which stages must see it (and which must not)
CHANGES = [
    ({"data_seed": 5}, "data"),
    ({"trajectories": 4}, "data"),
    ({"input_amplitude": 0.5}, "data"),
    ({"state_amplitude": 2.0}, "data"),
    ({"quantizer": QuantizerSpec(guard=False)}, "prep"),
    ({"noise": 0.01}, "prep"),
    ({"quantizer": QuantizerSpec(dither="tpdf")}, "channels"),
    ({"input_bits": "exact"}, "channels"),
    ({"dither_seed": 7}, "realizations"),
    ({"realizations": 3}, "realizations"),
    ({"theta": 0.25}, "bound"),
    ({"mpc": MPCConfig(horizon=5)}, "law loop"),
    ({"mpc": MPCConfig(x0=(1.0, 0.0, 0.0))}, "bound loop"),
    ({"mpc": MPCConfig(loop_seed=3)}, "loop"),
]


@pytest.mark.parametrize("change,group", CHANGES)
def test_a_changed_field_changes_exactly_the_keys_of_the_stages_that_use_it(change, group):
    system = get_system("dc-motor")
    new = dataclasses.replace(BASE, **change)
    for stage, groups in STAGE_GROUPS.items():
        changed = stage_key(BASE, system, stage) != stage_key(new, system, stage)
        assert changed == any(g in groups for g in group.split()), (change, stage)


def test_another_system_changes_every_key():
    a, b = get_system("dc-motor"), get_system("boeing747")
    assert all(stage_key(BASE, a, s) != stage_key(BASE, b, s) for s in STAGE_GROUPS)


def test_every_field_of_the_koopman_config_is_in_a_key_or_declared_keyless():
    from qsid_core.studies import KOOPMAN_KEY_PARTS, KOOPMAN_NOT_IN_KEYS, KOOPMAN_STAGE_GROUPS, KoopmanConfig

    paths = config_paths(KoopmanConfig)
    parts = {p for group in KOOPMAN_KEY_PARTS.values() for p in group}
    assert parts <= set(paths) and set(KOOPMAN_NOT_IN_KEYS) <= set(paths)
    assert {g for groups in KOOPMAN_STAGE_GROUPS.values() for g in groups} <= set(KOOPMAN_KEY_PARTS)
    covered = [p for p in paths if p in KOOPMAN_NOT_IN_KEYS or any(p == q or p.startswith(q + ".") for q in parts)]
    assert covered == paths, f"KoopmanConfig field(s) {sorted(set(paths) - set(covered))} are in no key"


@pytest.mark.parametrize(
    "change,stages",
    [
        ({"lifting": "poly:2"}, "reference reference-loop moments limit models loops"),
        ({"state_amplitude": 1.5}, "data reference reference-loop moments limit models loops"),
        ({"estimator": "bcls"}, "models loops"),
        ({"radius": 0.2}, "reference-loop loops"),
        ({"quantizer": QuantizerSpec(guard=False)}, "moments limit models loops"),
        ({"realizations": 3}, "moments models loops"),
        ({"prediction_horizon": 5}, "reference models"),  # the prediction errors; not the loops
    ],
)
def test_a_changed_koopman_field_changes_exactly_the_keys_that_use_it(change, stages):
    from qsid_core.studies import KOOPMAN_STAGE_GROUPS, KoopmanConfig, koopman_stage_key

    base = KoopmanConfig(trajectories=5, steps=10)
    new = dataclasses.replace(base, **change)
    for stage in KOOPMAN_STAGE_GROUPS:
        assert (koopman_stage_key(base, stage) != koopman_stage_key(new, stage)) == (stage in stages.split()), stage
