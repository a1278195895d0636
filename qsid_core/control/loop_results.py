"""The closed loops of several identified models on the true plant, and their verdicts."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["ClosedLoops"]


@dataclass
class ClosedLoops:
    """Closed loops of several identified models, each run on the true system.

    Attributes
    ----------
    states : ndarray, shape (R, steps + 1, n)
        True-system trajectories (NaN after a failure), in the system's state units.
    inputs : ndarray, shape (R, steps, m)
        Applied inputs (NaN after a failure).
    cost : ndarray, shape (R,)
        Realised cost ``sum_{t<steps} (x_t-r)'Q(x_t-r) + u_t'R u_t`` on the true system (NaN if failed).
    J0 : ndarray, shape (R,)
        Predicted optimal cost ``J*(x0)`` of the first MPC problem (NaN if failed).
    failure : list of str
        ``""`` for success, else a :class:`~qsid_core.errors.FailureKind` (a ``str``).
    messages : list of str
        Plain-words reason per failed realisation.
    qp_steps : int
        How many MPC steps needed the QP solver (the rest took the exact fast path).
    outcome : list of str
        Verdict per loop on the true plant (:mod:`qsid_core.verdicts`): ``"converged"``,
        ``"bounded"``, ``"diverged"`` or ``"failed"`` (the MPC could not run); empty when
        the loops were not judged (``MPCConfig.verify_steps=None``).
    spectral_radius : ndarray, shape (R,)
        ``max |eig(A - B K^)|`` of the unconstrained MPC law on the true plant (NaN where no MPC).
    verdict_steps : ndarray of int, shape (R,)
        Closed-loop steps it took to reach the verdict (``steps`` plus any extra steps).
    gains : list of ndarray (m, n) or None
        ``K^`` of each loop's unconstrained law ``u = -K^ x + k`` (None where no MPC ran).
    x_ref : ndarray, shape (n,) or (steps + 1, n), or None
        The reference the loops were steered to (constant, or ``r_0 .. r_steps``).
    """

    states: np.ndarray
    inputs: np.ndarray
    cost: np.ndarray
    J0: np.ndarray
    failure: list[str] = field(default_factory=list)
    messages: list[str] = field(default_factory=list)
    qp_steps: int = 0
    outcome: list[str] = field(default_factory=list)
    spectral_radius: np.ndarray | None = None
    verdict_steps: np.ndarray | None = None
    gains: list[np.ndarray | None] = field(default_factory=list)
    x_ref: np.ndarray | None = None

    @property
    def tracking_error(self) -> np.ndarray:
        """shape (R,): RMS of ``||x_t - r_t||`` over the whole loop (NaN where it failed)."""
        st = self.states
        ref = 0.0 if self.x_ref is None else self.x_ref
        with np.errstate(invalid="ignore"):
            rms: np.ndarray = np.sqrt(np.mean(np.sum((st - ref) ** 2, axis=2), axis=1))
        return rms

    @property
    def steady_state_error(self) -> np.ndarray:
        """shape (R,): RMS of ``||x_t - x_ref||`` over the last half of each loop (NaN where it failed).

        With a disturbance or a quantized measurement this is the residual the loop
        keeps; without them it is what is left of the transient.
        """
        st = self.states
        T = st.shape[1]
        ref: float | np.ndarray = 0.0 if self.x_ref is None else np.asarray(self.x_ref)
        if isinstance(ref, np.ndarray) and ref.ndim == 2:  # a time-varying reference, r_0 .. r_steps
            ref = ref[T // 2 :]
        with np.errstate(invalid="ignore"):
            rms: np.ndarray = np.sqrt(np.mean(np.sum((st[:, T // 2 :] - ref) ** 2, axis=2), axis=1))
        return rms

    @classmethod
    def empty(cls, loops: int, steps: int, n: int, m: int) -> ClosedLoops:
        """``loops`` loops of ``steps`` steps not run yet (NaN arrays, no failures)."""
        return cls(
            np.full((loops, steps + 1, n), np.nan),
            np.full((loops, steps, m), np.nan),
            np.full(loops, np.nan),
            np.full(loops, np.nan),
            [""] * loops,
            [""] * loops,
            0,
        )

    def outcome_counts(self) -> dict[str, int]:
        """``{"converged", "bounded", "diverged", "failed"}`` -> number of loops (empty if not judged)."""
        if not self.outcome:
            return {}
        return {k: sum(o == k for o in self.outcome) for k in ("converged", "bounded", "diverged", "failed")}

    @property
    def failed(self) -> np.ndarray:
        """shape (R,): True where the loop failed."""
        return np.array([bool(f) for f in self.failure])

    @property
    def final_state_norm(self) -> np.ndarray:
        """shape (R,): ``||x_steps||_2``."""
        norm: np.ndarray = np.linalg.norm(self.states[:, -1, :], axis=1)
        return norm
