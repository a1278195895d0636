"""Verdicts of the closed loops on the true plant: converged, bounded, diverged or failed.

How a short run ends says little: a loop whose linear law is unstable grows by
0.3 % a step and looks settled after 50 steps. Each loop is therefore judged on
the true plant by its unconstrained MPC law ``x+ = M x + c``, ``M = A - B K^``
(``K^`` the first gain of the MPC's own Riccati recursion, the law the MPC applies
whenever no bound is active), and by stepping on where that does not decide:

``converged``
    The spectral radius of ``M`` is below 1 and, from the current state, the
    unconstrained law satisfies every bound for all future steps (Lyapunov
    certificate, :func:`qsid_core.control.stability.certify`). The MPC then *is* that
    law forever, so ``||x_t - x_inf|| -> 0`` (``x_inf = x_ref`` when ``x_ref = 0``;
    a nonzero reference can leave an offset, reported apart). This is a proof,
    not a tolerance on the last sample.
``bounded``
    Did not converge and does not grow: the radius is >= 1 (the law cannot settle
    near its equilibrium) and the plant is stable, so ``|u| <= u_max`` keeps the
    state bounded (a stable plant with bounded input); or, after stepping on,
    the largest ``||x_t - x_ref||`` of two consecutive windows of
    :data:`WINDOW` steps changed by less than :data:`STALL` (relative); or the
    step budget ran out while it was not growing.
``diverged``
    The state left ``|x| <= 1e12`` (the run's own divergence test), or it was
    still growing by more than :data:`STALL` per window when the budget of
    ``MPCConfig.verify_steps`` extra steps ran out.
``failed``
    The MPC could not run (no model, no DARE solution, infeasible QP, solver failure).

The loops that need stepping continue from where the run stopped, in windows
of :data:`WINDOW` steps, with the same exact MPC law (fast path and QP) as the
run itself; only their verdicts are kept, not the extra trajectories.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from ..errors import FailureKind
from .loop_state import LoopState
from .stability import certify_batch, lyapunov_batch, spectral_radius

if TYPE_CHECKING:
    from .loop_results import ClosedLoops

__all__ = ["OUTCOMES", "WINDOW", "STALL", "judge"]

#: the verdicts, in the order they are counted
OUTCOMES = ("converged", "bounded", "diverged", "failed")
#: steps per window when a loop is stepped on to reach a verdict
WINDOW = 500
#: relative change of a window's largest deviation below which a loop is "not growing"
STALL = 1e-3


def _peak(states: np.ndarray, x_ref: np.ndarray) -> float:
    """Largest ``||x_t - x_ref||`` over a window (NaN-aware)."""
    d = np.linalg.norm(states - x_ref, axis=-1)
    d = d[np.isfinite(d)]
    return float(d.max()) if d.size else float("nan")


def _stalled(peak: float, before: float) -> bool:
    """The peak of a window is within :data:`STALL` of the window's before it (relative)."""
    return before > 0.0 and abs(peak / before - 1.0) < STALL


class _Judge:
    """The verdict state of every loop of one :func:`judge` call."""

    def __init__(self, loops: LoopState) -> None:
        self.loops = loops
        out = loops.out
        Rn, m = len(loops.ctrls), loops.m
        self.outcome = [""] * Rn
        self.steps = np.full(Rn, loops.steps, dtype=int)
        self.radius = np.full(Rn, np.nan)
        n = loops.n
        self.M = np.full((Rn, n, n), np.nan)
        self.c = np.full((Rn, n), np.nan)
        self.S = np.full((Rn, n, n), np.nan)
        for i, f in enumerate(out.failure):
            if f:
                self.outcome[i] = "diverged" if f == FailureKind.DIVERGED else "failed"
        self.live = [int(i) for i in loops.live if not out.failure[i]]
        if self.live:
            j = loops.rows(np.array(self.live))
            Fu, fu = loops.F[j, :m], loops.f[j, :m]
            M = loops.A[None] + np.einsum("ij,ljk->lik", loops.B, Fu)
            c = fu @ loops.B.T
            self.radius[self.live] = spectral_radius(M)
            self.M[self.live], self.c[self.live] = M, c
            self.S[self.live] = lyapunov_batch(M)[0]
        self.plant_stable = bool(spectral_radius(loops.A) < 1.0)
        self.peaks: dict[int, list[float]] = {i: [] for i in self.live}

    def certified(self, idx: ArrayLike, x: np.ndarray) -> np.ndarray:
        """Whether loops ``idx`` from states ``x[idx]`` provably stay on their (stable) unconstrained law."""
        idx = np.asarray(idx, dtype=int)
        if not idx.size:
            return np.zeros(0, dtype=bool)
        L = self.loops
        r = L.pos[idx]
        return certify_batch(self.M[idx], self.c[idx], L.F[r], L.f[r], L.bound, x[idx], S=self.S[idx])

    def first_look(self, x_end: np.ndarray) -> list[int]:
        """Verdicts from the run alone; returns the loops that need stepping on."""
        pending = []
        cert = dict(zip(self.live, self.certified(self.live, x_end)))
        for i in self.live:
            if cert[i]:
                self.outcome[i] = "converged"
            elif self.radius[i] >= 1.0 and self.plant_stable:
                self.outcome[i] = "bounded"
            else:
                pending.append(i)
        return pending

    def window(self, i: int, states: np.ndarray, x_ref: np.ndarray, done_steps: int, last: bool, cert: bool) -> None:
        """Update loop ``i`` after one window of extra steps (``states``: its trajectory over the window;
        ``cert``: whether its last state is certified to converge)."""
        peaks = self.peaks[i]
        peaks.append(_peak(states, x_ref))
        if cert or peaks[-1] == 0.0:  # certified, or sitting exactly on the reference for a whole window
            self.outcome[i] = "converged"
        elif len(peaks) >= 3 and all(_stalled(peaks[-k], peaks[-k - 1]) for k in (1, 2)):
            self.outcome[i] = "bounded"
        elif last:
            growing = len(peaks) >= 2 and peaks[-1] > peaks[-2] * (1.0 + STALL)
            self.outcome[i] = "diverged" if growing else "bounded"
        if self.outcome[i]:
            self.steps[i] = done_steps


def judge(
    loops: LoopState, budget: int, extend: Callable[[np.ndarray, int, Sequence[int]], tuple[ClosedLoops, np.ndarray]]
) -> None:
    """Give every loop of a finished run its verdict (fills ``outcome``, ``spectral_radius``, ``verdict_steps``,
    ``gains`` of ``loops.out``).

    Parameters
    ----------
    loops : qsid_core.control.loop_state.LoopState
        The run, after :func:`qsid_core.control.closed_loop.advance`; ``loops.out`` receives the verdicts.
    budget : int
        At most this many extra closed-loop steps per loop.
    extend : callable(x, k, active) -> (ClosedLoops, ndarray)
        Runs the loops ``active`` on from states ``x`` (R, n) for ``k`` steps; returns those
        steps and the states reached.
    """
    out = loops.out
    jd = _Judge(loops)
    x = np.array(loops.x)
    pending = jd.first_look(x)
    extra = 0
    while pending and extra < budget:
        k = min(WINDOW, budget - extra)
        scratch, x_next = extend(x, k, pending)
        extra += k
        last = extra >= budget
        ok = [i for i in pending if not scratch.failure[i]]
        x[ok] = x_next[ok]
        cert = dict(zip(ok, jd.certified(ok, x)))
        for i in pending:
            if scratch.failure[i]:
                jd.outcome[i] = "diverged" if scratch.failure[i] == FailureKind.DIVERGED else "failed"
                out.messages[i] = f"after {loops.steps + extra} steps: {scratch.messages[i]}"
                jd.steps[i] = loops.steps + extra
                continue
            jd.window(i, scratch.states[i], loops.w.x_ref, loops.steps + extra, last, bool(cert[i]))
        pending = [i for i in pending if not jd.outcome[i]]
    for i in pending:  # budget 0: no stepping allowed
        jd.outcome[i] = "bounded"
    out.outcome = jd.outcome
    out.gains = [None] * len(loops.ctrls)
    for i in jd.live:
        out.gains[i] = -loops.F[loops.pos[i], : loops.m].copy()
    out.spectral_radius = jd.radius
    out.verdict_steps = jd.steps
