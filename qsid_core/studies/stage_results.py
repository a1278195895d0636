"""Results of the stages of an :class:`~qsid_core.studies.experiment.Experiment` at one word length.

:class:`BitsIdentification` (the identified models of every dither realization),
:class:`TheoryAtBits` (Theorem 1's prediction and the letter's ultimate bound) and
:class:`ClosedLoops` (the MPC loops on the true plant and their verdicts).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..control.bound import UltimateBound

__all__ = ["BitsIdentification", "TheoryAtBits"]


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
        (:func:`qsid_core.control.controllability.controllability_margin`; NaN for a failed identification)."""
        margin = self._ctrb
        if margin is None:
            from ..control.controllability import controllability_margin

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
