"""Results of the stages of an :class:`~qsid_core.experiment.Experiment` at one word length.

:class:`BitsIdentification` (the identified models of every dither realization),
:class:`TheoryAtBits` (Theorem 1's prediction and the letter's ultimate bound) and
:class:`ClosedLoops` (the MPC loops on the true plant and their verdicts).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .theory import UltimateBound

__all__ = ["BitsIdentification", "TheoryAtBits", "ClosedLoops"]


@dataclass
class BitsIdentification:
    """Identification at one word length over all realizations.

    Attributes
    ----------
    bits : int
    eps : ndarray, shape (n+m,)
        Cell width per channel (states, then inputs).
    A_hat : ndarray, shape (R, n, n)
    B_hat : ndarray, shape (R, n, m)
    err_A, err_B : ndarray, shape (R,)
        Relative Frobenius errors.
    overload : ndarray, shape (R,)
        Overload fraction per realization.
    fallback : ndarray of bool, shape (R,)
        BCLS fell back to LS.
    notes : list of str
        Distinct explanations of fallbacks and failures.
    failed : ndarray of bool, shape (R,)
        Identification impossible (singular Psi Psi^T); the model is NaN and
        errors are NaN for that realization.
    dither : str
        The dither used; with ``"none"`` every realization is the same model.
    """

    bits: int
    eps: np.ndarray
    A_hat: np.ndarray
    B_hat: np.ndarray
    err_A: np.ndarray
    err_B: np.ndarray
    overload: np.ndarray
    fallback: np.ndarray
    notes: list[str]
    failed: np.ndarray = None  # type: ignore[assignment]  # None: no failures (set in __post_init__)
    dither: str = "subtractive"
    _ctrb: np.ndarray | None = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.failed is None:
            self.failed = np.zeros(len(self.err_A), dtype=bool)

    @property
    def realizations(self) -> int:
        """Number of realizations computed (R)."""
        return len(self.err_A)

    @property
    def effective_realizations(self) -> int:
        """Distinct realizations: 1 without dither (all R quantize the same data identically), else R."""
        return 1 if self.dither == "none" else self.realizations

    @property
    def models(self) -> list[tuple[np.ndarray, np.ndarray]]:
        return list(zip(self.A_hat, self.B_hat))

    @property
    def controllability(self) -> np.ndarray:
        """shape (R,): relative smallest singular value of the controllability matrix of each ``(A^, B^)``
        (:func:`qsid_core.stability.controllability_margin`; NaN for a failed identification)."""
        margin = self._ctrb
        if margin is None:
            from .stability import controllability_margin

            margin = controllability_margin(self.A_hat, self.B_hat)
            object.__setattr__(self, "_ctrb", margin)
        return margin

    @property
    def eigenvalues(self) -> np.ndarray:
        """Eigenvalues of A^ of every realization whose identification succeeded, shape (R_ok, n) complex."""
        A = self.A_hat[~self.failed]
        A = A[np.all(np.isfinite(A.reshape(len(A), -1)), axis=1)]
        n = self.A_hat.shape[1]
        eig: np.ndarray = np.linalg.eigvals(A) if len(A) else np.zeros((0, n), dtype=complex)
        return eig


@dataclass
class TheoryAtBits:
    """Theorem 1 prediction and the letter's ultimate bound at one word length.

    Attributes
    ----------
    bits : int
    G_pred : ndarray, shape (n, n+m)
        Theorem 1's large-data ``[A^, B^]``.
    err_A, err_B : float
        Its relative Frobenius errors.
    delta : float
        The letter's ultimate bound (state units; inf if no bound, NaN if Q or R is singular).
    bound_note : str
        Why there is no bound, in plain words.
    bound : UltimateBound or None
        All ingredients (``rho``, ``omega_v``, ``P`` eigenvalues, ``c_A``, ``c_B``, ``C``).
    """

    bits: int
    G_pred: np.ndarray
    err_A: float
    err_B: float
    delta: float
    bound_note: str = ""
    bound: UltimateBound | None = None

    @property
    def rho(self) -> float:
        """The ``rho`` the bound used (the automatic value unless configured; NaN without a bound)."""
        return float(self.bound.rho) if self.bound is not None else float("nan")


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
