"""Closed loops: the MPC built on each identified model, run on the true system.

:func:`run_closed_loops` runs many models at once. While the unconstrained LQ
optimum is feasible the MPC law is an affine feedback, so the loop is simulated
ahead and every predicted constraint checked in one batch; only the steps where
a bound is active solve a QP: the condensed box QPs of all such models at once by
primal-dual active-set iterations (compiled, :func:`qsid_core.quantization.kernels.box_qp_pdas`),
and DAQP (:mod:`qsid_core.control.condensed_qp`) where those do not settle or a state box
is set. Where the input box is the only constraint, the state is measured exactly
and the reference is constant, the whole loop runs compiled instead, the same law
step by step (:mod:`qsid_core.control.loop_kernel`). ``solver="osqp"`` runs the previous
engine's OSQP path instead. Failures are recorded per model, never raised.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from ..errors import FailureKind
from ..plant.lti import LTISystem
from .controllers import build_controllers
from .loop_fast import speculate
from .loop_kernel import eligible, run_compiled
from .loop_noise import FeedbackRange, loop_noise
from .loop_results import ClosedLoops
from .loop_state import DIVERGED, LoopState
from .loop_steps import step, step_small
from .mpc import MPCConfig
from .verdicts import judge

__all__ = ["run_closed_loops"]

#: at most this many models are stepped model by model (numpy's per-call overhead dominates tiny batches)
SMALL = 4

#: ``extend(x, k, active)``: the loops ``active`` run on from states ``x`` for ``k`` more steps
Extend = Callable[[np.ndarray, int, Sequence[int]], tuple[ClosedLoops, np.ndarray]]


def run_closed_loops(
    models: Sequence[tuple[np.ndarray, np.ndarray]],
    A_true: np.ndarray,
    B_true: np.ndarray,
    cfg: MPCConfig,
    system: LTISystem,
    feedback_range: FeedbackRange | None = None,
) -> ClosedLoops:
    """Run the MPC built on each model ``(A^, B^)`` in closed loop on the true system.

    Exact and fast: while the unconstrained LQ optimum is feasible, the MPC law
    is the affine feedback ``u = F_u x + f_u``, so the closed loop is simulated
    ahead for all models at once and every predicted constraint is checked in
    one batch. Models stay on that path until their first step where a
    constraint would be violated; from there on they are stepped one step at a
    time, with the QP solver (``cfg.solver``) on the steps where a bound is
    active, until a step where every remaining model is back on the fast path.
    A failure (no model, no DARE solution, infeasible QP, iteration limit,
    diverging state) is recorded for that model and never raised.

    Parameters
    ----------
    models : sequence of (A_hat, B_hat)
        Identified models, shapes (n, n) and (n, m); non-finite entries mean "no model".
    A_true, B_true : ndarray, shapes (n, n), (n, m)
        The true plant the inputs are applied to.
    cfg : MPCConfig
    system : LTISystem
        Supplies default Q, R and x0 (see :meth:`MPCConfig.resolve`).
    feedback_range : (lo, hi, guard), optional
        The training data's state range, for ``cfg.feedback_bits`` (:mod:`qsid_core.control.loop_noise`).
        With a disturbance or a quantized/noisy measurement the verdicts are those of
        the same MPC on the noise-free plant (the law's stability), except that a
        loop whose disturbed run diverged is ``diverged``.

    Returns
    -------
    ClosedLoops
    """
    w = cfg.resolve(system)
    n, m = B_true.shape
    Rn, steps = len(models), cfg.steps
    out = ClosedLoops.empty(Rn, steps, n, m)
    out.x_ref = w.x_ref
    ctrls = build_controllers(models, w, cfg, out.failure, out.messages)
    if all(c is None for c in ctrls):
        if cfg.verify_steps is not None:
            out.outcome = ["failed"] * Rn
            out.spectral_radius = np.full(Rn, np.nan)
            out.verdict_steps = np.zeros(Rn, dtype=int)
            out.gains = [None] * Rn
        return out
    noise = loop_noise(cfg, n, steps, feedback_range)
    loops = LoopState(ctrls, w, np.asarray(A_true, float), np.asarray(B_true, float), steps, out, noise=noise)
    if w.reference is not None:
        loops.offset_free = cfg.tracking == "offset-free"
        loops.track()
        out.x_ref = w.reference[: steps + 1]
    advance(loops, loops.live.copy())
    ok = np.array([not fl for fl in out.failure])
    out.cost[ok] = loops.acc[ok]
    out.J0[~ok] = np.nan
    if cfg.verify_steps is None:
        return out
    if noise is None and w.reference is None:
        judge(loops, cfg.verify_steps, _extender(loops))
    else:
        clean = run_closed_loops(models, A_true, B_true, cfg.nominal(), system)
        out.outcome = ["diverged" if f == FailureKind.DIVERGED else o for f, o in zip(out.failure, clean.outcome)]
        out.spectral_radius, out.verdict_steps, out.gains = clean.spectral_radius, clean.verdict_steps, clean.gains
    return out


def _extender(loops: LoopState) -> Extend:
    """``extend(x, k, active)``: run the loops ``active`` on from states ``x`` for ``k`` more steps.

    Returns the extra steps' :class:`ClosedLoops` and the states reached; the
    condensed QPs are shared with ``loops`` (built once).
    """

    def extend(x: np.ndarray, k: int, active: Sequence[int]) -> tuple[ClosedLoops, np.ndarray]:
        scratch = ClosedLoops.empty(len(loops.ctrls), k, loops.n, loops.m)
        ext = LoopState(loops.ctrls, loops.w, loops.A, loops.B, k, scratch, x_start=x, cq=loops.cq)
        advance(ext, np.array(active))
        loops.cq = ext.cq
        return scratch, ext.x

    return extend


def advance(loops: LoopState, active: np.ndarray) -> None:
    """Run the loops ``active`` for ``loops.steps`` steps: the fast path ahead, one step at a time where a bound is active."""
    if eligible(loops):  # box-only DAQP, exact feedback: the whole loop compiled
        run_compiled(loops, active, DIVERGED, loops.first_costs)
        return
    t, steps = 0, loops.steps
    with np.errstate(over="ignore", invalid="ignore"):
        while t < steps and active.size:
            active, t = speculate(loops, active, t)
            while t < steps and active.size:
                active, all_fast = (step_small if active.size <= SMALL else step)(loops, active, t)
                t += 1
                if all_fast:
                    break
