"""Closed-loop time series for display: x(t), u(t), saturation and ||x_t|| with a convergence floor.

Pure arrangement of :class:`~qsid_core.control.closed_loop.ClosedLoops` (no new numerics):
means and standard deviations over the successful loops, which steps have an
input on its bound, and the state norm with values below
``rel_floor * ||x0||`` marked as *converged* (floating-point noise of a
converged state, e.g. 1e-48, is not a meaningful distance to the origin; a log
axis should show the floor instead).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from ..errors import check_float

if TYPE_CHECKING:
    from .loop_results import ClosedLoops

__all__ = ["TimeSeries", "time_series", "CONVERGED_REL_FLOOR", "saturated_steps"]

#: Norms below this times ||x0|| count as converged.
CONVERGED_REL_FLOOR = 1e-12


@dataclass
class TimeSeries:
    """Closed loops of one model family as time series.

    Attributes
    ----------
    t : ndarray, shape (steps + 1,)
        Step index.
    states : ndarray, shape (R, steps + 1, n)
    inputs : ndarray, shape (R, steps, m)
    ok : ndarray of bool, shape (R,)
        Loops that did not fail.
    state_mean, state_std : ndarray, shape (steps + 1, n)
        Over the successful loops (NaN if there are none).
    input_mean, input_std : ndarray, shape (steps, m)
    u_max : ndarray, shape (m,), or None
        Input bounds (None: unbounded).
    saturated : ndarray of bool, shape (R, steps)
        Some input on its bound at that step.
    saturated_steps, saturated_loops : int
    norms : ndarray, shape (R, steps + 1)
        ``||x_t||`` (state units; NaN after a failure).
    norm_floor : float
        ``rel_floor * ||x0||``; norms below it are converged.
    converged : ndarray of bool, shape (R, steps + 1)
    norms_display : ndarray, shape (R, steps + 1)
        ``max(norms, norm_floor)``: safe for a log axis.
    """

    t: np.ndarray
    states: np.ndarray
    inputs: np.ndarray
    ok: np.ndarray
    state_mean: np.ndarray
    state_std: np.ndarray
    input_mean: np.ndarray
    input_std: np.ndarray
    u_max: np.ndarray | None
    saturated: np.ndarray
    saturated_steps: int
    saturated_loops: int
    norms: np.ndarray
    norm_floor: float
    converged: np.ndarray
    norms_display: np.ndarray


def _mean_std(a: np.ndarray, shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    if a.shape[0] == 0:
        return np.full(shape, np.nan), np.full(shape, np.nan)
    return a.mean(axis=0), a.std(axis=0)


def time_series(
    loops: ClosedLoops, x0: ArrayLike, u_max: ArrayLike | None = None, rel_floor: float = CONVERGED_REL_FLOOR
) -> TimeSeries:
    """Arrange closed loops as time series.

    Parameters
    ----------
    loops : ClosedLoops
        ``states`` (R, steps+1, n), ``inputs`` (R, steps, m), ``failure``.
    x0 : array_like, shape (n,)
        Initial state (sets the convergence floor).
    u_max : array_like, shape (m,), or None
        Input bounds.
    rel_floor : float in (0, 1)
        Convergence floor relative to ``||x0||`` (1 if x0 = 0).
    """
    rel_floor = check_float("rel_floor", rel_floor, 0.0, 1.0, lo_open=True, hi_open=True)
    X, U = np.asarray(loops.states, dtype=float), np.asarray(loops.inputs, dtype=float)
    ok = ~np.asarray(loops.failed, dtype=bool) if len(loops.failure) else np.ones(X.shape[0], dtype=bool)
    ok &= np.all(np.isfinite(X.reshape(X.shape[0], -1)), axis=1)
    sm, ss = _mean_std(X[ok], X.shape[1:])
    um, us = _mean_std(U[ok], U.shape[1:])
    umx = None if u_max is None else np.broadcast_to(np.asarray(u_max, dtype=float), U.shape[-1:]).copy()
    with np.errstate(invalid="ignore"):
        sat = np.any(np.abs(U) >= umx * (1 - 1e-9), axis=-1) if umx is not None else np.zeros(U.shape[:2], dtype=bool)
    k, loops_sat = saturated_steps(U, umx)
    norms = np.linalg.norm(X, axis=-1)
    r0 = float(np.linalg.norm(np.asarray(x0, dtype=float)))
    floor = rel_floor * (r0 if r0 > 0 else 1.0)
    with np.errstate(invalid="ignore"):
        conv = norms <= floor
        disp = np.where(np.isfinite(norms), np.maximum(norms, floor), np.nan)
    return TimeSeries(np.arange(X.shape[1]), X, U, ok, sm, ss, um, us, umx, sat, k, loops_sat, norms, floor, conv, disp)


def saturated_steps(inputs: np.ndarray, u_max: ArrayLike | None, rtol: float = 1e-9) -> tuple[int, int]:
    """Closed-loop steps where some input sits on its bound: ``(steps, loops with any)``.

    Parameters
    ----------
    inputs : ndarray, shape (R, steps, m)
        Applied inputs (NaN after a failure: not counted).
    u_max : array_like, shape (m,) or None
        Input bounds ``|u_j| <= u_max_j``; None means unbounded (0 saturated steps).
    """
    if u_max is None or inputs.size == 0:
        return 0, 0
    um = np.broadcast_to(np.asarray(u_max, dtype=float), inputs.shape[-1:])
    with np.errstate(invalid="ignore"):
        sat = np.any(np.abs(inputs) >= um * (1 - rtol), axis=-1)  # (R, steps); NaN compares False
    return int(sat.sum()), int(np.any(sat, axis=1).sum())
