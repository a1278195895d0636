"""The real loop: process disturbances on the true plant and a quantized, noisy state measurement.

With exact state feedback and no disturbance, every stabilizing model drives the
state to the reference, so beyond a few bits every loop looks the same. Real
loops are disturbed, and the controller measures the state through the same
kind of quantizer as the training data:

* **disturbance** ``w_t`` added to the true plant, ``x+ = A x + B u + w_t``:
  Gaussian with standard deviation ``sigma`` per state, or uniform with the same
  standard deviation (``U[-sqrt(3) sigma, sqrt(3) sigma]``);
* **feedback quantization**: the MPC sees ``y_t = Q(x_t + d_t) - d_t`` with
  subtractive dither ``d_t ~ U[-eps/2, eps/2]``, ``b_fb`` bits per state over the
  training data's range (the identification quantizer's range and guard band);
* **sensor noise** ``v_t ~ N(0, sigma_v^2)`` added to that measurement.

Every draw comes from one seeded stream shared by all loops (every b, estimator
and the true-model loop see the same ``w_t``, ``d_t``, ``v_t``), so curves over b
compare like with like.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from ..quantization.quantize import effective_ranges

if TYPE_CHECKING:
    from .mpc import MPCConfig

__all__ = ["DISTURBANCES", "FeedbackRange", "LoopNoise", "loop_noise"]

#: distributions of the process disturbance
DISTURBANCES = ("gaussian", "uniform")


#: ``(lo, hi, guard)`` of the training data's channels: the range of a quantized measurement in the loop.
FeedbackRange = tuple[ArrayLike, ArrayLike, bool]


@dataclass(frozen=True, eq=False)
class LoopNoise:
    """Disturbance and measurement draws of one closed-loop run, shape (steps, n) each.

    Attributes
    ----------
    w : ndarray, shape (steps, n)
        Process disturbance added at each step (zeros without one).
    dither : ndarray, shape (steps, n) or None
        Unit dither draws ``U[-1/2, 1/2]`` of the feedback quantizer (None: exact feedback).
    v : ndarray, shape (steps, n) or None
        Sensor noise (None: none).
    lo, eps : ndarray, shape (n,) or None
        The feedback quantizer's lower bound and cell width per state.
    levels : int
        ``2**b_fb``.
    """

    w: np.ndarray
    dither: np.ndarray | None = None
    v: np.ndarray | None = None
    lo: np.ndarray | None = None
    eps: np.ndarray | None = None
    levels: int = 0

    def measure(self, x: np.ndarray, t: int) -> np.ndarray:
        """What the controller sees of states ``x`` (shape (L, n)) at step ``t``."""
        y = x
        if self.dither is not None:
            d = self.eps * self.dither[t]
            cell = np.clip(np.floor((x + d - self.lo) / self.eps), 0, self.levels - 1)
            y = self.lo + (cell + 0.5) * self.eps - d
        if self.v is not None:
            y = y + self.v[t]
        return y


def loop_noise(cfg: MPCConfig, n: int, steps: int, feedback_range: FeedbackRange | None = None) -> LoopNoise | None:
    """The draws of ``cfg`` (an :class:`~qsid_core.control.mpc.MPCConfig`) for ``steps`` steps (None: a clean loop).

    Parameters
    ----------
    cfg : MPCConfig
        ``disturbance``, ``disturbance_kind``, ``feedback_bits``, ``feedback_noise``, ``loop_seed``.
    n : int
        Number of states.
    steps : int
    feedback_range : (lo, hi, guard), optional
        The training data's state range and the guard-band choice; needed with ``feedback_bits``.
    """
    if not cfg.disturbance and cfg.feedback_bits is None and not cfg.feedback_noise:
        return None
    rng = np.random.default_rng(np.random.SeedSequence(cfg.loop_seed))
    # fixed draw order (disturbance, dither, noise): each stream is the same whatever else is switched on
    if cfg.disturbance_kind == "uniform":
        raw = rng.uniform(-np.sqrt(3.0), np.sqrt(3.0), size=(steps, n))
    else:
        raw = rng.standard_normal((steps, n))
    w = cfg.disturbance * raw
    unit = rng.random((steps, n)) - 0.5
    noise = rng.standard_normal((steps, n))
    v = cfg.feedback_noise * noise if cfg.feedback_noise else None
    if cfg.feedback_bits is None:
        return LoopNoise(w=w, v=v)
    if feedback_range is None:
        raise ValueError("feedback quantization needs the training data's range")
    lo, hi, guard = feedback_range
    lo_q, eps = effective_ranges(np.asarray(lo, float)[:n], np.asarray(hi, float)[:n], cfg.feedback_bits, guard)
    return LoopNoise(w=w, v=v, dither=unit, lo=lo_q, eps=eps, levels=2**cfg.feedback_bits)
