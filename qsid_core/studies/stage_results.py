"""Results of the stages of an :class:`~qsid_core.studies.experiment.Experiment` at one word length.

:class:`BitsIdentification` (the identified models of every dither realization),
:class:`TheoryAtBits` (Theorem 1's prediction and the letter's ultimate bound) and
:class:`ClosedLoops` (the MPC loops on the true plant and their verdicts).

A nonlinear plant's (:class:`~qsid_core.studies.KoopmanExperiment`): :class:`KoopmanModels` (the lifted model of
every realization and its row) and the row itself: each realization's model recorded with its errors against the
unquantized EDMD and its prediction error (:func:`record`, :func:`predict`), then the statistics over the
realizations, the closed loops and the estimator's large-data limit (:func:`row`, :func:`loop_entries`,
:func:`large_data_entry`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..control import KoopmanLoops
from ..control.bound import UltimateBound
from ..errors import IdentificationError
from ..identification import (
    KoopmanModel,
    LargeDataLimit,
    LiftedMoments,
    Lifting,
    MonomialLifting,
    edmd,
    lifted_error,
    prediction_errors,
)
from ..plant import NonlinearDataset, NonlinearSystem
from ..quantization import QuantizerSpec

__all__ = [
    "ACC_KEYS",
    "BitsIdentification",
    "KoopmanModels",
    "TheoryAtBits",
    "large_data_entry",
    "loop_entries",
    "no_exact_correction",
    "predict",
    "record",
    "row",
]


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


@dataclass(frozen=True)
class KoopmanModels:
    """The models of every realization at one word length and estimator, and their row.

    Attributes
    ----------
    bits : int
    estimator : str
    models : tuple of KoopmanModel or None
        One per realization (None: identification failed).
    row : dict
        The row of :class:`~qsid_core.studies.KoopmanResult` without the loops (``stabilized_fraction`` and
        ``closed_loop_outcomes`` None) and with ``large_data``.
    """

    bits: int
    estimator: str
    models: tuple[KoopmanModel | None, ...]
    row: dict[str, Any]


#: What :func:`record` and :func:`predict` collect per word length, one entry per realization.
ACC_KEYS = ("G", "A", "B", "pred", "fallback", "notes", "models", "over", "eps")


def _stats(v: list[float]) -> dict[str, float]:
    a = np.asarray(v, dtype=float)
    a = a[np.isfinite(a)]
    if a.size == 0:
        return {"mean": float("nan"), "std": float("nan")}
    return {"mean": float(a.mean()), "std": float(a.std())}


def record(
    acc: dict[str, list[Any]],
    mom: LiftedMoments,
    estimator: str,
    lifting: Lifting,
    ref: KoopmanModel,
) -> None:
    """Add one realization at one word length to ``acc``: its model (None when identification failed), the
    lifted errors against ``ref``, the overload fraction, ``eps`` and notes (the prediction error:
    :func:`predict`)."""
    acc["over"].append(mom.overload_fraction)
    acc["eps"].append(mom.eps)
    try:
        model: KoopmanModel | None = edmd(mom, lifting.C, estimator)
    except IdentificationError as exc:
        model = None
        acc["notes"].append(str(exc))
    if model is None:
        for k in ("G", "A", "B"):
            acc[k].append(float("nan"))
    else:
        eG, eA, eB = lifted_error(model, ref)
        acc["G"].append(eG)
        acc["A"].append(eA)
        acc["B"].append(eB)
        acc["fallback"].append(model.fallback)
        if model.note:
            acc["notes"].append(model.note)
    acc["models"].append(model)


def predict(per: list[dict[str, list[Any]]], lifting: Lifting, held: NonlinearDataset, horizon: int) -> None:
    """Add the prediction error on ``held`` of the model last recorded in each of ``per`` (NaN where
    identification failed), all in one batch."""
    models = [acc["models"][-1] for acc in per]
    ok = [mo for mo in models if mo is not None]
    errs = iter(prediction_errors(ok, lifting, held, horizon))
    for acc, mo in zip(per, models, strict=True):
        acc["pred"].append(float("nan") if mo is None else next(errs))


def large_data_entry(
    limit: LargeDataLimit | None, estimator: str, ref: KoopmanModel, correction: str
) -> dict[str, Any]:
    """The row's ``large_data`` entry: where the estimator goes with many samples (:func:`large_data_limit`)."""
    if estimator == "bcls":
        if correction:
            return {"err_G": None, "note": f"no exact limit: {correction}"}
        return {"err_G": 0.0, "note": "the de-biased moments are unbiased: the limit is the unquantized EDMD"}
    if limit is None or limit.model is None:
        return {"err_G": None, "note": "not computed" if limit is None else limit.note}
    return {"err_G": lifted_error(limit.model, ref)[0], "note": ""}


def row(b: int, acc: dict[str, list[Any]], system: NonlinearSystem) -> dict[str, Any]:
    """The result row of word length ``b`` from its realizations ``acc``; the closed loops' entries are None until
    :func:`loop_entries` fills them in."""
    n = system.n
    return {
        "bits": b,
        "eps_x": np.asarray(acc["eps"][0][:n]).tolist(),
        "eps_u": np.asarray(acc["eps"][0][n:]).tolist(),
        "err_G": _stats(acc["G"]),
        "err_A": _stats(acc["A"]),
        "err_B": _stats(acc["B"]),
        "prediction_error": _stats(acc["pred"]),
        "overload_fraction": float(np.mean(acc["over"])),
        "bcls_fallbacks": int(sum(acc["fallback"])),
        "ident_failures": int(sum(m is None for m in acc["models"])),
        "realizations": len(acc["models"]),
        "stabilized_fraction": None,
        "closed_loop_outcomes": None,
        "within_radius": None,
        "settled_offset": None,
        "notes": sorted(set(acc["notes"])),
    }


def loop_entries(loops: KoopmanLoops) -> dict[str, Any]:
    """A row's loop entries: the stabilized (converged) share, the outcome counts, how many ended within the
    convergence radius and the settled offsets' median and max (:class:`~qsid_core.control.KoopmanLoops`)."""
    return {
        "stabilized_fraction": loops.converged_fraction,
        "closed_loop_outcomes": loops.counts(),
        "within_radius": int(np.sum(loops.within_radius)),
        "settled_offset": loops.offset_stats(),
    }


def no_exact_correction(lifting: Lifting, spec: QuantizerSpec) -> str:
    """Why the de-biased moments are not exact for this dictionary and dither ("" when they are)."""
    if not isinstance(lifting, MonomialLifting):
        return f"the radial functions of {lifting.spec} have no exact correction (LS is used)"
    if spec.dither != "subtractive":
        return f"the Bernoulli correction is exact for subtractive dither only, not {spec.dither}"
    return ""
