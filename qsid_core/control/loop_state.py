"""The state of a batch of closed loops (:class:`LoopState`): the controllers, the true plant, what each loop
has recorded so far, and the small operations every stepping method shares (measure, move, cost, fail).

The stepping lives beside it: :mod:`~qsid_core.control.loop_fast` (the fast path run ahead),
:mod:`~qsid_core.control.loop_steps` (one step at a time where a bound is active) and
:mod:`~qsid_core.control.loop_kernel` (the whole loop compiled); :mod:`~qsid_core.control.closed_loop`
drives them.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import FailureKind
from .condensed_qp import CondensedQP, condense
from .controller import MPCController
from .loop_noise import LoopNoise
from .loop_results import ClosedLoops
from .mpc_weights import MPCWeights
from .tracking import Preview

Floats = NDArray[np.float64]

__all__ = ["DIVERGED", "Floats", "LoopState"]

#: a state beyond this norm (max-abs) counts as diverged
DIVERGED = 1e12


class LoopState:
    """State of the batched closed loops (arrays indexed by realisation ``i``)."""

    def __init__(
        self,
        ctrls: Sequence[MPCController | None],
        w: MPCWeights,
        A: Floats,
        B: Floats,
        steps: int,
        out: ClosedLoops,
        x_start: Floats | None = None,
        cq: CondensedQP | None = None,
        noise: LoopNoise | None = None,
    ) -> None:
        self.ctrls, self.w, self.A, self.B, self.steps, self.out = ctrls, w, A, B, steps, out
        self.noise = noise  # disturbance and measurement draws (None: exact state feedback, no disturbance)
        self.preview: Preview | None = None  # a time-varying reference (None: the constant x_ref)
        self.offset_free = False  # the input cost (u - u_ref)'R(u - u_ref) instead of the letter's u'R u
        self.n, self.m = B.shape
        live = np.flatnonzero([c is not None for c in ctrls])
        self.live = live
        cs = [self.ctrl(i) for i in live]
        # fast-path prediction maps of the live models: z = F x + f stacks u_0..u_{N-1} [, x_1..x_N]
        self.F = np.stack([c.F for c in cs])  # (L, rows, n)
        self.f = np.stack([c.f for c in cs])  # (L, rows)
        self.bound = cs[0].bound  # (rows,)
        self.pos = np.full(len(ctrls), -1)  # realisation -> row of the live arrays
        self.pos[live] = np.arange(live.size)
        self.acc = np.zeros(len(ctrls))  # realised cost so far
        # current true state per realisation (x0, or where an earlier run stopped)
        self.x = np.tile(w.x0, (len(ctrls), 1)) if x_start is None else np.array(x_start, dtype=float)
        out.states[live, 0] = self.x[live]
        self.first_costs = x_start is None  # record J*(x0) of the first problem (not for a continued run)
        self.cq = cq  # condensed QPs of the live models (built at the first constrained step)
        # box-only problems solved by DAQP: guess the active set in one batch, DAQP only where the guess fails
        self.solver_is_daqp = cs[0].solver == "daqp"
        self.guess = self.solver_is_daqp and self.bound.size == cs[0].N * self.m  # no state rows
        self.nU = cs[0].N * self.m  # condensed variables u_0..u_{N-1}
        self.prevU = np.full((len(ctrls), self.nU), np.nan)  # last optimal input sequence per model
        self.prev_t = np.full(len(ctrls), -2)  # the step it was computed at
        self.ub = np.tile(w.u_max, self.nU // self.m)  # box of U = [u_0; ...; u_{N-1}]

    def ctrl(self, i: int | np.integer[Any]) -> MPCController:
        """The controller of realisation ``i``, a live one (a model without a controller never runs)."""
        c = self.ctrls[int(i)]
        assert c is not None, f"realisation {int(i)} has no controller and never runs"
        return c

    def live_ctrls(self) -> list[MPCController]:
        """The controllers of the live realisations, in the order of the live-model arrays."""
        return [self.ctrl(i) for i in self.live]

    def qps(self) -> CondensedQP:
        """The condensed QPs of the live models (condensed, once, on first use)."""
        self.condensed(attach=False)
        assert self.cq is not None  # set by condensed()
        return self.cq

    def seen(self, x: np.ndarray, t: int) -> np.ndarray:
        """What the controller measures of true states ``x`` (shape (L, n)) at step ``t``."""
        return x if self.noise is None else self.noise.measure(x, t)

    def moved(self, x: np.ndarray, u: np.ndarray, t: int) -> np.ndarray:
        """The true plant's next states ``A x + B u`` (+ the disturbance at step ``t``)."""
        xn = x @ self.A.T + u @ self.B.T
        return xn if self.noise is None else xn + self.noise.w[t]

    def rows(self, active: NDArray[np.integer[Any]]) -> NDArray[np.int64]:
        """Rows of the live-model arrays (``F``, ``f``, the condensed QPs) of realisations ``active``."""
        rows: NDArray[np.int64] = self.pos[active]
        return rows

    def track(self) -> None:
        """Follow ``w.reference`` with preview (the controllers were built for a zero reference)."""
        self.condensed()
        cs = self.live_ctrls()
        free = (np.stack([c.A for c in cs]), np.stack([c.B for c in cs]), self.w.R) if self.offset_free else None
        assert self.w.reference is not None  # tracking is switched on only with a reference
        self.preview = Preview(self.qps(), self.F.shape[1], self.w.reference, free)

    def ref_offsets(self, j: np.ndarray, t: int, H: int) -> Floats | float:
        """The reference part of the prediction map at steps ``t..t+H-1`` (0 without a time-varying reference)."""
        return 0.0 if self.preview is None else self.preview.offsets(j, t, H)

    def stage_cost(self, xs: np.ndarray, us: np.ndarray, t: int = 0) -> np.ndarray:
        """``(x - r)'Q(x - r) + u'R u`` over the last axis (``xs`` from step ``t``)."""
        # a time-varying reference runs along the time axis (second to last) from step t
        e = xs - (self.w.x_ref if self.preview is None else self.preview.r[t : t + xs.shape[-2]])
        cost: Floats = np.einsum("...i,ij,...j->...", e, self.w.Q, e) + np.einsum("...i,ij,...j->...", us, self.w.R, us)
        return cost

    def fail(self, i: int, kind: FailureKind, msg: str) -> None:
        """Record loop ``i`` as failed (``kind``, ``msg``); its states and inputs become NaN."""
        self.out.failure[i], self.out.messages[i] = kind, msg
        self.out.states[i] = np.nan
        self.out.inputs[i] = np.nan

    def first_cost(self, i: int, y: np.ndarray, U: np.ndarray) -> float:
        """``J*(x0)`` of loop ``i``'s first problem from its unconstrained optimum ``U``."""
        c = self.ctrl(i)
        if self.preview is None:
            return c.cost_to_go(y)
        self.preview.set_qp(c.daqp(), self.pos[i], 0)
        return c.qp_cost(y, U)

    def condensed(self, attach: bool = True) -> None:
        """Condense the QPs of all live models in one batch (once) and, with ``attach``, hand them to the
        controllers (the compiled loop attaches a model only when its DAQP solver is needed: :meth:`attach`)."""
        if self.cq is not None:
            return
        cs = self.live_ctrls()
        c0 = cs[0]
        self.cq = condense(
            np.stack([c.A for c in cs]),
            np.stack([c.B for c in cs]),
            c0.Q,
            c0.R,
            np.stack([c.Qf for c in cs]),
            c0.x_ref,
            c0.N,
        )
        if attach:
            for k, c in enumerate(cs):
                c.use_condensed(self.cq, k)

    def attach(self, i: int) -> None:
        """Hand realisation ``i``'s condensed QP to its controller (for its DAQP solver)."""
        self.ctrl(i).use_condensed(self.qps(), int(self.pos[i]))
