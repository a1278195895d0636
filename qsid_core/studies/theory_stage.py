"""The theory stages of an :class:`~qsid_core.studies.experiment.Experiment`: Theorem 1's prediction with the
letter's ultimate bound at one word length, and the a-posteriori bound of each realization's own model."""

from __future__ import annotations

import numpy as np

from ..control.bound import UltimateBound, riccati_finite, ultimate_bound
from ..control.mpc import MPCConfig
from ..control.realized_bound import RealizedBounds, realized_bounds
from ..control.riccati import dare_batch, dare_stabilizing
from ..errors import ConfigError, MPCFailure
from ..identification.identify import relative_errors
from ..identification.theorem1 import theorem1_prediction
from ..quantization.quantize import channel_bits, channel_eps
from .executors import single_threaded_blas
from .stage_cache import Staged
from .stage_results import TheoryAtBits

__all__ = ["realized_bound_at", "theory_at"]


def theory_at(ex: Staged, b: int) -> TheoryAtBits:
    """Theorem 1's large-data model at ``b`` and the ultimate bound of the MPC built on it.

    The MPC settings are the config's (the defaults when MPC is off). A bound that cannot be computed is
    ``inf`` (no MPC on the predicted model) or ``nan`` (settings that do not apply), with the reason as note.
    """
    c = ex.config
    mcfg = c.mpc or MPCConfig()
    prep = ex.prepared
    sysm = ex.system
    n = sysm.n
    q = c.quantizer
    chan = channel_bits(b, n, sysm.m, c.input_bits, c.state_bits)
    eps = channel_eps(prep.lo, prep.hi, chan, q.guard, q.dither)
    # the LS limit with white sensor noise on the states: Sigma (noise-free) + D + sigma^2
    Gp = theorem1_prediction(sysm.G, ex.Sigma, eps, q.dither, ex.noise_variance())
    eA, eB = relative_errors(Gp[:, :n], Gp[:, n:], sysm.A, sysm.B)
    w = mcfg.resolve(sysm)
    note, ub = "", None
    delta: float
    try:
        Qf = w.Qf if w.Qf is not None else _terminal_weight(Gp[:, :n], Gp[:, n:], w.Q, w.R)
        P = riccati_finite(Gp[:, :n], Gp[:, n:], w.Q, w.R, Qf, mcfg.horizon)
        ub = ultimate_bound(P, w.Q, w.R, sysm.A - Gp[:, :n], sysm.B - Gp[:, n:], theta=c.theta, rho=c.rho, x0=w.x0)
        delta, note = ub.delta, ub.note
    except MPCFailure as exc:
        delta, note = float("inf"), str(exc)
    except np.linalg.LinAlgError:
        delta, note = float("inf"), "no bound: the Riccati recursion of the predicted model is singular"
    except ConfigError as exc:
        delta, note = float("nan"), str(exc)
    bound: UltimateBound | None = ub
    return TheoryAtBits(b, Gp, eA, eB, delta, note, bound)


def _terminal_weight(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray) -> np.ndarray:
    """The stabilizing DARE solution of one model, shape (n, n): by doubling (:func:`dare_batch`), else by
    :func:`dare_stabilizing`, whose :class:`MPCFailure` says why there is none."""
    X, ok = dare_batch(A[None], B[None], Q, R)
    return X[0] if ok[0] else dare_stabilizing(A, B, Q, R)


def realized_bound_at(ex: Staged, b: int, est: str) -> RealizedBounds:
    """The a-posteriori ultimate bound of each realization's model ``est`` identifies at ``b``
    (:func:`qsid_core.control.realized_bound.realized_bounds`; the MPC settings are the config's, or the defaults)."""
    c = ex.config
    mcfg = c.mpc or MPCConfig()
    w = mcfg.resolve(ex.system)
    with single_threaded_blas():
        return realized_bounds(
            ex.identification(b, est).models,
            ex.system.A,
            ex.system.B,
            w.Q,
            w.R,
            w.Qf,
            mcfg.horizon,
            theta=c.theta,
            rho=c.rho,
            x0=w.x0,
        )
