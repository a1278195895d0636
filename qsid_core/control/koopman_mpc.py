"""Koopman MPC (Korda & Mezic 2018): the letter's MPC on a lifted model, run on the true (nonlinear) plant.

For a lifted predictor ``z+ = A_z z + B_z u``, ``x = C z`` (:class:`~qsid_core.identification.KoopmanModel`)
the controller is :class:`~qsid_core.control.controller.MPCController` on ``(A_z, B_z)`` with the output cost
``(x - r)'Q(x - r) = z' C'QC z`` (``r = 0``), the input box and horizon of :class:`MPCConfig`. Every step
the true state is measured exactly, lifted (``z = psi(x)``), and the first optimal input is applied to the
true plant for one sample (one RK4 step of a :class:`~qsid_core.plant.NonlinearSystem`, or ``A x + B u``
of an :class:`~qsid_core.plant.LTISystem`).

The terminal weight is ``C' Qf C`` when ``MPCConfig.Qf`` is given; else, for the identity lifting, the
DARE solution of the model, as for the linear loops (so the identity lifting on a linear plant is exactly
the linear MPC); else the stage weight ``C'QC`` (Korda & Mezic): a lifted model's DARE is ill-posed, since
its constant observable is an eigenvalue 1 that is neither controllable nor weighted, and a model from
quantized data that perturbs that row would get a DARE solution from a nearly uncontrollable mode.

Verdict per loop (stated, not certified: the linear certificates do not apply to a nonlinear plant), as the
linear loops are judged: ``diverged`` when the state left the plant's sane box (``|x_i| > box``) or stopped being
finite, ``failed`` when no MPC could be built or solved, else ``converged`` when its *settled offset* (the mean
2-norm of the state over the last :data:`SETTLED_SHARE` of the steps) is at most :data:`SETTLED_TOLERANCE`
``|x0|``, and ``bounded`` (ultimately bounded, at that offset) otherwise. A lifted model with a constant
observable has an affine term a quantized (or merely finite) data set leaves nonzero, so its loop typically
settles near, not at, the origin. Whether the final state is within ``radius`` (default
:data:`CONVERGED_RADIUS`) is reported apart (``within_radius``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Protocol, cast

import numpy as np

from ..errors import MPCFailure
from ..plant import LTISystem, NonlinearSystem
from .controller import MPCController
from .mpc import MPCConfig

__all__ = ["CONVERGED_RADIUS", "SETTLED_SHARE", "SETTLED_TOLERANCE", "KoopmanLoops", "LiftedModel", "run_koopman_loops"]

#: A loop whose final state has 2-norm at most this is ``within_radius`` (reported apart from the verdict).
CONVERGED_RADIUS = 0.1
#: The settled offset is the mean 2-norm of the state over this last share of the loop's steps.
SETTLED_SHARE = 0.1
#: A loop converged when its settled offset is at most this times ``|x0|`` (else it is bounded at that offset).
SETTLED_TOLERANCE = 1e-6


class LiftedModel(Protocol):
    """What the loops need of a lifted model: ``A`` (L, L), ``B`` (L, m), ``C`` (n, L)."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray


class _Lift(Protocol):
    def lift(self, x: np.ndarray) -> np.ndarray: ...


@dataclass
class KoopmanLoops:
    """Closed loops of lifted models on the true plant.

    Attributes
    ----------
    states : ndarray, shape (k, steps + 1, n)
        True-plant trajectories (NaN after a failure or once the state left the box).
    inputs : ndarray, shape (k, steps, m)
    outcome : list of str
        ``converged`` / ``bounded`` / ``diverged`` / ``failed`` per loop (the module docstring).
    radius : float
        The radius of ``within_radius``.
    notes : list of str
        Per loop: why it failed ("" otherwise).
    settled_offset : ndarray, shape (k,)
        Mean 2-norm of the state over the last :data:`SETTLED_SHARE` of the steps (NaN: diverged or failed).
    within_radius : ndarray of bool, shape (k,)
        The final state is within ``radius`` (a loop that diverged or failed is not).
    """

    states: np.ndarray
    inputs: np.ndarray
    outcome: list[str]
    radius: float
    notes: list[str] = field(default_factory=list)
    settled_offset: np.ndarray = field(default_factory=lambda: np.zeros(0))
    within_radius: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))

    def offset_stats(self) -> dict[str, float] | None:
        """``{"median", "max"}`` of the settled offsets of the loops that did not diverge or fail (None: none)."""
        ok = self.settled_offset[np.isfinite(self.settled_offset)]
        return {"median": float(np.median(ok)), "max": float(np.max(ok))} if ok.size else None

    def counts(self) -> dict[str, int]:
        """How many loops ended in each outcome."""
        return {k: self.outcome.count(k) for k in ("converged", "bounded", "diverged", "failed")}

    @property
    def converged_fraction(self) -> float:
        """Share of the loops that converged."""
        return self.outcome.count("converged") / max(len(self.outcome), 1)


def _weights(system: LTISystem | NonlinearSystem, cfg: MPCConfig) -> SimpleNamespace:
    """The MPC weights, input box and start for ``system`` (the nonlinear plants carry diagonals)."""
    if isinstance(system, NonlinearSystem):
        view = SimpleNamespace(
            n=system.n,
            m=system.m,
            Q=np.diag(system.Q),
            R=np.diag(system.R),
            x0=np.array(system.x0),
            name=system.name,
            state_names=system.state_names,
        )
        w = cfg.resolve(cast(LTISystem, view))  # resolve reads n, m, Q, R, x0, name, state_names only
    else:
        w = cfg.resolve(system)
    return SimpleNamespace(Q=w.Q, R=w.R, Qf=w.Qf, x0=w.x0, u_max=w.u_max, x_ref=w.x_ref)


def _controller(model: LiftedModel, w: SimpleNamespace, cfg: MPCConfig, dare: bool) -> MPCController:
    """The MPC on the lifted model: terminal weight ``C'Qf C``, else the DARE's (``dare``), else ``C'QC``."""
    C = np.asarray(model.C, dtype=float)
    Qz = C.T @ w.Q @ C
    Qf = C.T @ w.Qf @ C if w.Qf is not None else (None if dare else Qz)
    return MPCController(
        model.A, model.B, Qz, w.R, cfg.horizon, w.u_max, x_ref=np.zeros(Qz.shape[0]), Qf=Qf, eps=cfg.eps,
        max_iter=cfg.max_iter, solver=cfg.solver,
    )  # fmt: skip


def _controllers(
    models: Sequence[LiftedModel | None], w: SimpleNamespace, cfg: MPCConfig, dare: bool, notes: list[str]
) -> list[MPCController | None]:
    """The MPC of every model (None, with its note, where there is no model or it cannot be built)."""
    out: list[MPCController | None] = []
    for i, model in enumerate(models):
        if model is None:
            notes[i] = "no model: identification failed"
            out.append(None)
            continue
        try:
            out.append(_controller(model, w, cfg, dare))
        except MPCFailure as exc:
            notes[i] = f"{exc.kind}: {exc}"
            out.append(None)
    return out


def _inputs(
    rows: np.ndarray, ctrls: list[MPCController | None], Z: np.ndarray, u_max: np.ndarray, notes: list[str], m: int
) -> tuple[np.ndarray, np.ndarray]:
    """The first optimal input of every running loop ``rows`` (lifted states ``Z``): (the rows whose MPC solved,
    their inputs clipped to the box, shape (k, m)); a loop whose MPC fails gets its note, its controller dropped."""
    U: list[np.ndarray] = []
    ok: list[int] = []
    for j, r in enumerate(rows.tolist()):
        ctrl = ctrls[r]
        assert ctrl is not None
        try:
            u, _, _ = ctrl.solve(Z[j])
        except MPCFailure as exc:
            notes[r], ctrls[r] = f"{exc.kind}: {exc}", None
            continue
        U.append(np.clip(u, -u_max, u_max))
        ok.append(r)
    return np.asarray(ok, dtype=int), np.asarray(U, dtype=float).reshape(len(ok), m)


def run_koopman_loops(
    models: Sequence[LiftedModel | None],
    lifting: _Lift,
    system: LTISystem | NonlinearSystem,
    cfg: MPCConfig | None = None,
    radius: float = CONVERGED_RADIUS,
) -> KoopmanLoops:
    """Run the MPC of each lifted model in closed loop on the true plant.

    Parameters
    ----------
    models : sequence of KoopmanModel or None
        None: no model (the loop is ``failed``).
    lifting : Lifting
        ``psi`` of the models (the measured state is lifted every step).
    system : NonlinearSystem or LTISystem
        The true plant (its x0, Q, R unless ``cfg`` sets them).
    cfg : MPCConfig, optional
        Horizon, steps, input box, weights (disturbances and quantized feedback are not used here).
    radius : float
        Convergence radius of the verdict.

    Returns
    -------
    KoopmanLoops
    """
    cfg = cfg or MPCConfig()
    w = _weights(system, cfg)
    k, n, m, steps = len(models), system.n, system.m, cfg.steps
    states = np.full((k, steps + 1, n), np.nan)
    inputs = np.full((k, steps, m), np.nan)
    outcome = ["failed"] * k
    notes = [""] * k
    box = system.box if isinstance(system, NonlinearSystem) else 1e12
    ctrls = _controllers(models, w, cfg, getattr(lifting, "spec", "") == "identity", notes)
    # every loop steps in lockstep: one batched plant step and lift per sample (the MPC is solved per loop)
    alive = np.array([c is not None for c in ctrls], dtype=bool)
    left = np.zeros(k, dtype=bool)
    x = np.tile(np.asarray(w.x0, dtype=float), (k, 1))
    states[alive, 0] = x[alive]
    for t in range(steps):
        running = np.flatnonzero(alive)
        if running.size == 0:
            break
        rows, U = _inputs(running, ctrls, lifting.lift(x[running]), w.u_max, notes, m)
        for r in np.setdiff1d(running, rows).tolist():  # its MPC failed: failed, no trajectory
            states[r], inputs[r], alive[r] = np.nan, np.nan, False
        if rows.size == 0:
            break
        inputs[rows, t] = U
        with np.errstate(all="ignore"):
            if isinstance(system, NonlinearSystem):
                xn = system.step(x[rows], U)
            else:
                xn = x[rows] @ system.A.T + U @ system.B.T
        x[rows] = xn
        states[rows, t + 1] = xn
        with np.errstate(invalid="ignore"):
            out = ~np.all(np.isfinite(xn), axis=1) | (np.max(np.abs(xn), axis=1) > box)
        left[rows[out]] = True
        alive[rows[out]] = False
    tail = max(1, int(np.ceil(SETTLED_SHARE * steps)))
    with np.errstate(invalid="ignore"):
        offset = np.linalg.norm(states[:, -tail:], axis=2).mean(axis=1)
    tol = SETTLED_TOLERANCE * float(np.linalg.norm(w.x0))
    within = np.zeros(k, dtype=bool)
    for i in range(k):
        if ctrls[i] is None or not np.isfinite(offset[i]) or left[i]:
            offset[i] = np.nan
            if ctrls[i] is not None:
                outcome[i] = "diverged"
            continue
        outcome[i] = "converged" if offset[i] <= tol else "bounded"
        within[i] = float(np.linalg.norm(x[i])) <= radius
    return KoopmanLoops(states, inputs, outcome, float(radius), notes, offset, within)
