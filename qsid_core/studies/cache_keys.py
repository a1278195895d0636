"""Cache keys of a study's stages for both plant kinds, generated from the engine configs' fields.

Every field of :class:`~qsid_core.SweepConfig` (and of its nested :class:`~qsid_core.QuantizerSpec`
and :class:`~qsid_core.MPCConfig`) is either a part of one of the key groups in :data:`KEY_PARTS` or
listed in :data:`NOT_IN_KEYS` with the reason it needs none; ``tests/core/studies/test_cache_keys.py``
fails for a field that is neither, so a new setting cannot leave cached results silently stale.

A stage's key is the system's matrices followed by the values of the groups it depends on
(:data:`STAGE_GROUPS`); the stage's own name and per-call parts (b, the estimator) are added by
:class:`~qsid_core.Experiment`.

A nonlinear plant's study (:class:`~qsid_core.studies.KoopmanConfig`) has its own groups and stages
(:data:`KOOPMAN_KEY_PARTS`, :data:`KOOPMAN_NOT_IN_KEYS`, :data:`KOOPMAN_STAGE_GROUPS`), held to the same rule:
its nested :class:`~qsid_core.QuantizerSpec` and :class:`~qsid_core.MPCConfig` are key parts as wholes, and the
plant (a preset's name, a plant file's path, or a :class:`~qsid_core.plant.NonlinearSystem` by identity) starts
every key (:func:`koopman_stage_key`). The settings table says from these which results a setting invalidates
(:meth:`app.settings.schema.Setting.stages`).
"""

from __future__ import annotations

from dataclasses import fields, is_dataclass
from typing import Any

from ..control.mpc import MPCConfig
from ..plant.lti import LTISystem
from .config import KoopmanConfig, SweepConfig

__all__ = [
    "KEY_PARTS",
    "KOOPMAN_KEY_PARTS",
    "KOOPMAN_NOT_IN_KEYS",
    "KOOPMAN_STAGE_GROUPS",
    "NOT_IN_KEYS",
    "STAGE_GROUPS",
    "config_paths",
    "group_values",
    "koopman_stage_key",
    "stage_key",
    "system_key",
]

#: Groups of key parts: dotted paths into a :class:`SweepConfig` (``"mpc"`` alone = every MPC field).
KEY_PARTS: dict[str, tuple[str, ...]] = {
    # the simulated training data
    "data": ("trajectories", "steps", "data_seed", "input_amplitude", "state_amplitude"),
    # the recorded data normalised to the quantizer's ranges
    "prep": ("quantizer.range_mode", "quantizer.guard", "quantizer.fixed_range", "noise"),
    # the word length and the dither of each channel
    "channels": ("quantizer.dither", "input_bits", "state_bits"),
    # the dither realizations and what BCLS is told
    "realizations": ("dither_seed", "realizations", "noise_known"),
    # the MPC law the theory assumes (MPC off: MPCConfig()'s values)
    "law": ("mpc.horizon", "mpc.Q", "mpc.R", "mpc.Qf"),
    # the ultimate bound
    "bound": ("theta", "rho", "mpc.x0"),
    # the closed loops: the whole MPC configuration
    "loop": ("mpc",),
}

#: Fields that are in no key group, and why none is needed.
NOT_IN_KEYS: dict[str, str] = {
    "system": "its matrices (A, B, x0, Q, R) start every key (system_key)",
    "bits": "the sweep's list; each key holds the one word length b it is for",
    "estimator": "the default estimator; each identification key holds the estimator asked for",
}

#: The key groups each stage depends on, in order.
STAGE_GROUPS: dict[str, tuple[str, ...]] = {
    "data": ("data",),
    "prep": ("data", "prep"),
    "mom": ("data", "prep", "channels", "realizations"),
    "theory": ("data", "prep", "channels", "law", "bound"),
    "overload-effect": ("data", "prep", "channels"),
    "realized-bound": ("data", "prep", "channels", "realizations", "law", "bound"),
    "small-gain": ("law",),  # of Theorem 1's predicted model, which is part of its key
    "ident": ("data", "prep", "channels", "realizations"),
    "assumptions": ("data", "prep", "channels", "realizations"),
    "loops": ("data", "prep", "channels", "realizations", "loop"),
    "own-small-gain": ("data", "prep", "channels", "realizations"),  # of the loops' own models; holds the gains
    "true-loop": ("loop",),
    "true-loop-fed": ("data", "prep", "loop"),  # a quantized measurement uses the training data's range
}


def config_paths(cls: type = SweepConfig, prefix: str = "") -> list[str]:
    """Dotted paths of every field of ``cls``, nested dataclass configs expanded (``quantizer.dither``, ...)."""
    from ..quantization.quantize import QuantizerSpec

    nested: dict[str, type] = {"quantizer": QuantizerSpec, "mpc": MPCConfig}
    out = []
    for f in fields(cls):
        path = prefix + f.name
        out.append(path)
        if not prefix and f.name in nested:
            out += config_paths(nested[f.name], path + ".")
    return out


def _value(config: SweepConfig, path: str) -> Any:
    obj: Any = config
    for i, part in enumerate(path.split(".")):
        if part == "mpc" and obj.mpc is None and i < path.count("."):  # a part of the bound with MPC off
            obj = MPCConfig()
            continue
        obj = getattr(obj, part)
    assert not is_dataclass(obj) or path == "mpc"  # a key part is a plain, hashable value (or the frozen MPC)
    return obj


def group_values(config: SweepConfig, group: str) -> tuple[Any, ...]:
    """The values of key group ``group`` (:data:`KEY_PARTS`) in ``config``."""
    return tuple(_value(config, p) for p in KEY_PARTS[group])


def system_key(system: LTISystem) -> tuple[Any, ...]:
    """The system's shapes and matrices (A, B, x0, Q, R) as bytes: the start of every key."""
    s = system
    assert s.x0 is not None and s.Q is not None and s.R is not None  # filled in LTISystem.__post_init__
    return (s.A.shape, s.B.shape, s.A.tobytes(), s.B.tobytes(), s.x0.tobytes(), s.Q.tobytes(), s.R.tobytes())


def stage_key(config: SweepConfig, system: LTISystem, stage: str, *extra: Any) -> tuple[Any, ...]:
    """The cache key of ``stage`` (:data:`STAGE_GROUPS`): its name, ``extra`` (b, estimator), the system, its groups."""
    return (stage, *extra, *system_key(system), *(v for g in STAGE_GROUPS[stage] for v in group_values(config, g)))


#: Groups of a nonlinear sweep's key parts: dotted paths into a :class:`KoopmanConfig` (as
#: :data:`~qsid_core.studies.cache_keys.KEY_PARTS` for the linear sweeps).
KOOPMAN_KEY_PARTS: dict[str, tuple[str, ...]] = {
    # the training and held-out runs (and the RBF centres: drawn over the amplitude, seeded by data_seed)
    "data": ("trajectories", "steps", "data_seed", "input_amplitude", "state_amplitude", "box"),
    "lifting": ("lifting",),
    "quantizer": ("quantizer",),
    "realizations": ("dither_seed", "realizations"),
    "estimator": ("estimator",),
    "prediction": ("prediction_horizon",),
    # the Koopman MPC and its verdict
    "loop": ("mpc", "radius"),
}
#: :class:`KoopmanConfig` fields in no key group, and why none is needed.
KOOPMAN_NOT_IN_KEYS: dict[str, str] = {
    "system": "the plant starts every key (a preset by name, any other plant by identity)",
    "bits": "the sweep's list; each key holds the one word length b it is for",
}
#: The key groups each result of a nonlinear sweep depends on.
KOOPMAN_STAGE_GROUPS: dict[str, tuple[str, ...]] = {
    "data": ("data",),
    "reference": ("data", "lifting", "prediction"),  # the unquantized EDMD and its prediction error
    "reference-loop": ("data", "lifting", "loop"),
    "moments": ("data", "lifting", "quantizer", "realizations"),  # quantized lifted moments (every estimator's)
    "limit": ("data", "lifting", "quantizer"),  # the large-data limit of LS quantized EDMD
    "models": ("data", "lifting", "quantizer", "realizations", "estimator", "prediction"),  # with prediction errors
    "loops": ("data", "lifting", "quantizer", "realizations", "estimator", "loop"),
}


def koopman_stage_key(cfg: KoopmanConfig, stage: str, *extra: Any) -> tuple[Any, ...]:
    """The cache key of a nonlinear sweep's result ``stage`` (:data:`KOOPMAN_STAGE_GROUPS`): its name, ``extra``
    (e.g. b), the plant (a preset's name or a plant file's path; a :class:`~qsid_core.plant.NonlinearSystem` itself, which
    compares by identity), and the values of the stage's key groups."""
    values: list[Any] = []
    for group in KOOPMAN_STAGE_GROUPS[stage]:
        for path in KOOPMAN_KEY_PARTS[group]:
            obj: Any = cfg
            for part in path.split("."):
                obj = getattr(obj, part)
            values.append(obj)
    return (stage, *extra, cfg.system, *values)
