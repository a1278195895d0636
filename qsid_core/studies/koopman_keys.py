"""Cache keys of a nonlinear sweep's results (:class:`~qsid_core.studies.KoopmanConfig`), as
:mod:`~qsid_core.studies.cache_keys` has them for the linear sweeps.

Every field of :class:`KoopmanConfig` (its nested :class:`~qsid_core.QuantizerSpec` and
:class:`~qsid_core.MPCConfig` as wholes) is a part of one key group of :data:`KOOPMAN_KEY_PARTS` or listed in
:data:`KOOPMAN_NOT_IN_KEYS`; ``tests/core/studies/test_cache_keys.py`` fails for a field that is neither. The
settings table says from these which results a setting of a nonlinear run invalidates
(:meth:`app.settings.schema.Setting.stages`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .koopman_sweep import KoopmanConfig

__all__ = ["KOOPMAN_KEY_PARTS", "KOOPMAN_NOT_IN_KEYS", "KOOPMAN_STAGE_GROUPS", "koopman_stage_key"]

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
