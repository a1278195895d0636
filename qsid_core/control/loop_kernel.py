"""The saturated MPC closed loop compiled end to end (numba): no Python per step.

For box-only MPC (input bounds, no state box), exact state feedback, no
disturbance and a constant reference, :func:`run_compiled` runs every loop of a
:class:`qsid_core.control.loop_state.LoopState` for all its steps inside one compiled
kernel, step by step, with the same law as the batched numpy path:

* the unconstrained LQ optimum ``z = F x + f`` (the fast path) where it meets the box;
* else the condensed box QP by primal-dual active-set iterations
  (:func:`qsid_core.quantization.kernels._pdas_one_py`), warm-started from the previous step's
  optimal sequence shifted by one step (receding horizon), or at the first
  constrained step of a stretch from the bounds the unconstrained optimum violates;
* the true plant moves, ``x+ = A x + B u``; a state beyond the divergence bound ends the loop.

A loop leaves the kernel at a step it cannot settle (iteration limit, a free block
of the Hessian not numerically definite): that step is solved by the model's DAQP
solver in Python (warm start, exact failure kinds), then the kernel goes on from the
next step. A loop that reaches its first constrained step before the condensed
QPs exist leaves the kernel too; they are built once and the kernel resumes.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, DTypeLike, NDArray

from ..errors import FailureKind, MPCFailure
from ..quantization import kernels
from .loop_state import LoopState

__all__ = ["eligible", "run_compiled", "PDAS_ITERS"]

#: active-set iterations per constrained step before the step goes to DAQP
PDAS_ITERS = 8
#: relative slack of the KKT checks (rounding only)
TOL = 1e-12
# why a loop left the kernel
_DONE, _NEED_QP, _UNSETTLED, _DIVERGED = 0, 1, 2, 3

_Floats = NDArray[np.float64]
_Ints = NDArray[np.int64]
_Bools = NDArray[np.bool_]


def _predict_py(F: _Floats, f: _Floats, bound: _Floats, r: int, xs: _Floats, z: _Floats) -> bool:
    """``z = F[r] xs + f[r]``; whether it meets the box (the unconstrained optimum is the MPC's)."""
    fast = True
    for k in range(z.shape[0]):
        s = f[r, k]
        for c in range(xs.shape[0]):
            s += F[r, k, c] * xs[c]
        z[k] = s
        if not abs(s) <= bound[k]:
            fast = False
    return fast


def _guess_py(
    Gx: _Floats,
    g0: _Floats,
    r: int,
    xs: _Floats,
    z: _Floats,
    prevU: _Floats,
    prev_t: _Ints,
    i: int,
    t: int,
    ub: _Floats,
    m: int,
    g: _Floats,
    up: _Bools,
    lo: _Bools,
) -> None:
    """The QP's ``g = Gx[r] xs + g0[r]`` and the active-set guess: the last step's optimal sequence shifted
    by one step when the last step was a QP step, else the bounds the unconstrained optimum ``z`` violates."""
    nU = ub.shape[0]
    warm = prev_t[i] == t - 1
    for k in range(nU):
        s = g0[r, k]
        for c in range(xs.shape[0]):
            s += Gx[r, k, c] * xs[c]
        g[k] = s
        if warm:
            base = prevU[i, k + m] if k + m < nU else prevU[i, k]
        else:
            base = z[k]
        up[k] = base >= ub[k] * (1 - 1e-9)
        lo[k] = (base <= -ub[k] * (1 - 1e-9)) and not up[k]


def _move_py(A: _Floats, B: _Floats, xs: _Floats, u: _Floats, xn: _Floats, diverged: float) -> bool:
    """``xn = A xs + B u``; False if a component leaves ``|x| <= diverged`` (or is not finite)."""
    ok = True
    for k in range(xn.shape[0]):
        s = 0.0
        for c in range(xs.shape[0]):
            s += A[k, c] * xs[c]
        for c in range(u.shape[0]):
            s += B[k, c] * u[c]
        xn[k] = s
        if not abs(s) <= diverged:
            ok = False
    return ok


def _stage_py(xs: _Floats, x_ref: _Floats, Q: _Floats, u: _Floats, R: _Floats) -> float:
    """``(x - r)'Q(x - r) + u'R u``."""
    cost = 0.0
    for k in range(xs.shape[0]):
        for c in range(xs.shape[0]):
            cost += (xs[k] - x_ref[k]) * Q[k, c] * (xs[c] - x_ref[c])
    for k in range(u.shape[0]):
        for c in range(u.shape[0]):
            cost += u[k] * R[k, c] * u[c]
    return cost


def _box_loop_py(
    idx: _Ints, rows: _Ints, t0: _Ints, steps: int, F: _Floats, f: _Floats, bound: _Floats, H: _Floats,
    Gx: _Floats, g0: _Floats, have_qp: bool, A: _Floats, B: _Floats, Q: _Floats, R: _Floats, x_ref: _Floats,
    ub: _Floats, iters: int, tol: float, diverged: float, x: _Floats, prevU: _Floats, prev_t: _Ints,
    states: _Floats, inputs: _Floats, acc: _Floats, U0: _Floats, first: NDArray[np.int8], qp_steps: _Ints,
    status: _Ints, tstop: _Ints,
) -> None:  # fmt: skip
    """Run loops ``idx`` (rows ``rows`` of ``F``, ``H``, ...) from steps ``t0`` until done or stopped."""
    n, m, nU = F.shape[2], B.shape[1], ub.shape[0]
    z, g, U = np.empty(F.shape[1]), np.empty(nU), np.empty(nU)
    up, lo = np.empty(nU, dtype=np.bool_), np.empty(nU, dtype=np.bool_)
    Lc, rhs, free = np.empty((nU, nU)), np.empty(nU), np.empty(nU, dtype=np.int64)
    u, xn = np.empty(m), np.empty(n)
    for a in range(idx.shape[0]):
        i, r = idx[a], rows[a]
        xs = x[i]
        status[a] = _DONE
        for t in range(t0[a], steps):
            if _predict(F, f, bound, r, xs, z):
                for c in range(m):
                    u[c] = z[c]
                if t == 0:
                    first[a] = 1
            else:
                if not have_qp:
                    status[a], tstop[a] = _NEED_QP, t
                    break
                _guess(Gx, g0, r, xs, z, prevU, prev_t, i, t, ub, m, g, up, lo)
                if not kernels._pdas_one(H[r], g, ub, up, lo, iters, tol, U, Lc, rhs, free):
                    status[a], tstop[a] = _UNSETTLED, t
                    break
                qp_steps[a] += 1
                prevU[i, :] = U
                prev_t[i] = t
                for c in range(m):  # the active set meets the bounds up to rounding: clip that rounding
                    u[c] = min(max(U[c], -ub[c]), ub[c])
                if t == 0:
                    first[a] = 2
                    U0[a, :] = U
            if not _move(A, B, xs, u, xn, diverged):
                status[a], tstop[a] = _DIVERGED, t
                break
            acc[i] += _stage(xs, x_ref, Q, u, R)
            states[i, t + 1, :] = xn
            inputs[i, t, :] = u
            xs[:] = xn


if kernels.AVAILABLE:
    _jit = kernels._numba.njit(cache=True, nogil=True)
    _predict, _guess, _move, _stage = _jit(_predict_py), _jit(_guess_py), _jit(_move_py), _jit(_stage_py)
    _box_loop = _jit(_box_loop_py)
else:  # pragma: no cover
    _predict, _guess, _move, _stage = _predict_py, _guess_py, _move_py, _stage_py
    _box_loop = None


def eligible(loops: LoopState) -> bool:
    """Whether :func:`run_compiled` can run ``loops``: numba present, DAQP on box-only problems,
    exact state feedback, no disturbance, no time-varying reference."""
    return kernels.AVAILABLE and loops.guess and loops.noise is None and loops.preview is None


def _own(a: ArrayLike, dtype: DTypeLike = float) -> NDArray[Any]:
    """A writable C-contiguous copy: the kernel is compiled for one array type, not also for read-only
    (shared-memory) or strided inputs, so a cache written by any process serves every process."""
    return np.array(a, dtype=dtype, order="C")


class _Kernel:
    """The kernel's arguments for the live models of ``loops`` (the condensed QPs once built)."""

    def __init__(self, loops: LoopState, diverged: float) -> None:
        self.loops, self.diverged = loops, float(diverged)
        w = loops.w
        self.F, self.f = _own(loops.F), _own(loops.f)
        self.fixed = (
            _own(loops.A),
            _own(loops.B),
            _own(w.Q),
            _own(w.R),
            _own(w.x_ref),
            _own(loops.ub),
        )
        self.qp: tuple[_Floats, _Floats, _Floats] | None = None

    def need_qp(self) -> None:
        if self.qp is None:
            cq = self.loops.qps()
            self.qp = (_own(cq.H), _own(cq.Gx), _own(cq.g0))

    def run(self, idx: _Ints, t0: _Ints) -> tuple[_Ints, _Ints, NDArray[np.int8], _Floats]:
        """Run loops ``idx`` from steps ``t0``; returns ``(status, tstop, first, U0)`` per loop."""
        L, k = self.loops, idx.size
        nU = L.ub.size
        if self.qp is None:
            n = L.n
            qp = (np.zeros((1, nU, nU)), np.zeros((1, nU, n)), np.zeros((1, nU)))
        else:
            qp = self.qp
        U0 = np.full((k, nU), np.nan)
        first = np.zeros(k, dtype=np.int8)
        qp_steps = np.zeros(k, dtype=np.int64)
        status = np.zeros(k, dtype=np.int64)
        tstop = np.full(k, L.steps, dtype=np.int64)
        out = L.out
        _box_loop(
            idx, L.rows(idx), t0, L.steps, self.F, self.f, _own(L.bound), *qp,
            self.qp is not None, *self.fixed, PDAS_ITERS, TOL, self.diverged,
            L.x, L.prevU, L.prev_t, out.states, out.inputs, L.acc, U0, first, qp_steps, status, tstop,
        )  # fmt: skip
        out.qp_steps += int(qp_steps.sum())
        return status, tstop, first, U0


def run_compiled(loops: LoopState, active: NDArray[np.integer[Any]], diverged: float, first_costs: bool) -> None:
    """Run the loops ``active`` of ``loops`` for ``loops.steps`` steps in the compiled kernel.

    Fills ``loops.out`` (states, inputs, ``qp_steps``, failures, and ``J0`` when
    ``first_costs``: the loops start at ``loops.w.x0``), ``loops.acc`` and ``loops.x``
    as :func:`qsid_core.control.closed_loop.advance` does.
    """
    kern = _Kernel(loops, diverged)
    idx = _own(active, dtype=np.int64)
    t0 = np.zeros(idx.size, dtype=np.int64)
    while idx.size:
        status, tstop, first, U0 = kern.run(idx, t0)
        if first_costs:
            _first_costs(loops, idx, t0, first, U0)
        go_on, at = [], []
        for a in np.flatnonzero(status != _DONE):
            i, t = int(idx[a]), int(tstop[a])
            if status[a] == _DIVERGED:
                loops.fail(i, FailureKind.DIVERGED, f"closed loop diverged at step {t + 1}")
                continue
            kern.need_qp()
            if status[a] == _UNSETTLED:
                if not _daqp_step(loops, i, t, diverged, first_costs):
                    continue
                t += 1
            go_on.append(i)
            at.append(t)
        idx, t0 = np.array(go_on, dtype=np.int64), np.array(at, dtype=np.int64)


def _first_costs(loops: LoopState, idx: _Ints, t0: _Ints, first: NDArray[np.int8], U0: _Floats) -> None:
    """``J*(x0)`` of the loops whose first step the kernel took: the unconstrained optimal cost where
    the fast path held, else the condensed QP's cost ``U'HU + 2 g'U + c(x0)`` of the active-set solution."""
    x0, out, w = loops.w.x0, loops.out, loops.w
    fast = idx[(t0 == 0) & (first == 1)]
    if fast.size:
        parts = [loops.ctrl(i).parts for i in fast]
        P0, p0 = np.stack([p.P0 for p in parts]), np.stack([p.p0 for p in parts])
        out.J0[fast] = np.einsum("i,lij,j->l", x0, P0, x0) + 2 * p0 @ x0 + np.array([p.c0 for p in parts])
    sel = np.flatnonzero((t0 == 0) & (first == 2))
    if sel.size:
        cq, j, U = loops.qps(), loops.rows(idx[sel]), U0[sel]
        g = cq.Gx[j] @ x0 + cq.g0[j]
        e = cq.Sx[j] @ x0 - np.tile(w.x_ref, cq.Sx.shape[1] // x0.size)
        d0 = x0 - w.x_ref
        out.J0[idx[sel]] = (
            np.einsum("li,lij,lj->l", U, cq.H[j], U)
            + 2 * np.einsum("li,li->l", g, U)
            + np.einsum("li,lij,lj->l", e, cq.Qbars[j], e)
            + d0 @ w.Q @ d0
        )


def _daqp_step(loops: LoopState, i: int, t: int, diverged: float, first_costs: bool) -> bool:
    """Step ``t`` of loop ``i`` by its DAQP solver (warm-started); False if the loop failed there."""
    c, out = loops.ctrl(i), loops.out
    loops.attach(i)
    x = loops.x[i].copy()
    out.qp_steps += 1
    try:
        U = c.solve_daqp(x)
    except MPCFailure as exc:
        loops.fail(i, exc.kind, f"step {t}: {exc}")
        return False
    loops.prevU[i], loops.prev_t[i] = U, t
    if t == 0 and first_costs:
        out.J0[i] = c.qp_cost(x, U)
    u = np.clip(U[: loops.m], -loops.w.u_max, loops.w.u_max)
    xn = loops.moved(x[None], u[None], t)[0]
    if not np.all(np.isfinite(xn)) or np.abs(xn).max() > diverged:
        loops.fail(i, FailureKind.DIVERGED, f"closed loop diverged at step {t + 1}")
        return False
    out.states[i, t + 1], out.inputs[i, t] = xn, u
    loops.acc[i] += loops.stage_cost(x[None], u[None], t)[0]
    loops.x[i] = xn
    return True
