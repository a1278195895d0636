"""The budget study of a :class:`~qsid_core.studies.study.Study`'s settings: at a fixed budget of bits, the model
error and the loops against the word length, without sensor noise and, when the settings have some, with it.

This is what :meth:`Study.frames <qsid_core.studies.study.Study.frames>` yields last when the study is given a
budget (its ``"budget"`` frame): :func:`~qsid_core.studies.budget.run_budget` of the study's own configuration
(its word lengths, run length, realizations, quantizer, estimator, seeds and MPC; the runs set by the budget),
once with the sensor noise set to zero and once as set. A budget sends every channel at the swept b, so a
what-if word length per channel is not used (said in ``notes``); a budget that identifies nothing at any b is
``error``, not an exception, so a front end shows it where the curves would be. Given bits per sample, it also
runs the per-channel allocation at the configuration's settings (:func:`~qsid_core.studies.run_allocation`: the
proposed split against the uniform one); where that does not apply (a nonlinear plant, dither other than
subtractive, bits per sample out of range) the reason is ``allocation_note`` instead.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Executor
from dataclasses import dataclass, fields, replace
from typing import Any

from ..errors import ConfigError
from ..plant.systems import get_system
from .budget import BudgetConfig, BudgetResult, run_budget
from .budget_allocation import AllocationResult, run_allocation
from .cache_keys import system_key
from .config import KoopmanConfig, SweepConfig

__all__ = ["Bandwidth", "bandwidth", "bandwidth_key"]


class _Cancelled(Exception):
    """Raised from the budget's progress callback when the caller's cancel check says stop."""


@dataclass(frozen=True)
class Bandwidth:
    """A budget study at one configuration.

    Attributes
    ----------
    total_bits : float
    estimator : str
    noise_free : BudgetResult or None
        Without sensor noise (None: ``error``).
    noisy : BudgetResult or None
        With the configuration's sensor noise (None: it has none, or a nonlinear plant, which has no noise setting).
    notes : tuple of str
        Settings the budget does not use.
    error : str
        Why nothing was computed ("" when it was).
    allocation : AllocationResult or None
        The per-channel allocation at the bits per sample given (None: none given, or see ``allocation_note``).
    allocation_note : str
        Why no allocation was computed although bits per sample were given ("" otherwise).
    """

    total_bits: float
    estimator: str
    noise_free: BudgetResult | None
    noisy: BudgetResult | None = None
    notes: tuple[str, ...] = ()
    error: str = ""
    allocation: AllocationResult | None = None
    allocation_note: str = ""


def bandwidth_key(
    config: SweepConfig | KoopmanConfig, total_bits: float, estimator: str, bits_per_sample: int | None = None
) -> tuple[Any, ...]:
    """The cache key of :func:`bandwidth`'s result: every setting it depends on (a linear plant's matrices as
    bytes, every other field exactly by ``repr``), not the sweep's own data size ``trajectories``."""
    head: tuple[Any, ...] = ("bandwidth", float(total_bits), estimator, bits_per_sample)
    if isinstance(config, SweepConfig):
        head += system_key(get_system(config.system))
    rest = tuple(
        (f.name, repr(getattr(config, f.name)))
        for f in fields(config)
        if f.name not in ("trajectories", "estimator") and not (f.name == "system" and isinstance(config, SweepConfig))
    )
    return head + rest


def bandwidth(
    config: SweepConfig | KoopmanConfig,
    total_bits: float,
    estimator: str | None = None,
    executor: Executor | None = None,
    cancel: Callable[[], bool] | None = None,
    bits_per_sample: int | None = None,
) -> Bandwidth | None:
    """The budget study of ``config`` at ``total_bits`` (None: cancelled, ``cancel()`` said so between realizations).

    ``estimator`` (default the config's) is the one whose models are judged; ``bits_per_sample``: also the
    per-channel allocation of that many bits per sample (module docstring).
    """
    est = estimator or config.estimator
    notes: list[str] = []
    base: SweepConfig | KoopmanConfig = replace(config, estimator=est)
    if isinstance(base, SweepConfig) and (base.input_bits is not None or base.state_bits is not None):
        base = replace(base, input_bits=None, state_bits=None)
        notes.append("the word length per channel is not used: a budget sends every channel at b")

    def progress(_done: int, _total: int, _stage: str) -> None:
        if cancel is not None and cancel():
            raise _Cancelled

    try:
        if isinstance(base, SweepConfig):
            quiet = replace(base, noise=(0.0,))
            noise_free = run_budget(BudgetConfig(total_bits, quiet), executor, progress)
            noisy = run_budget(BudgetConfig(total_bits, base), executor, progress) if any(base.noise) else None
        else:
            noise_free, noisy = run_budget(BudgetConfig(total_bits, base), executor, progress), None
    except _Cancelled:
        return None
    except ConfigError as exc:
        return Bandwidth(float(total_bits), est, None, None, tuple(notes), str(exc))
    out = Bandwidth(float(total_bits), est, noise_free, noisy, tuple(notes))
    if bits_per_sample is None:
        return out
    try:
        alloc = run_allocation(BudgetConfig(total_bits, base, bits_per_sample=bits_per_sample), executor, progress)
    except _Cancelled:
        return None
    except ConfigError as exc:  # a nonlinear plant, another dither, too few or too many bits: said, not raised
        return replace(out, allocation_note=str(exc))
    return replace(out, allocation=alloc)
