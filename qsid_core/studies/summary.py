"""The typed per-word-length summary of a sweep (:class:`SummaryRow`) and strict-JSON helpers.

:meth:`SummaryRow.to_dict` gives the JSON of ``qsid sweep --json``'s ``results``
entries: the keys and values of earlier versions plus ``realizations``,
``effective_realizations``, ``rho``, ``ultimate_bound_realized``, ``assumptions``
and ``saturated_steps``. Every number is finite or ``None`` (never NaN or inf).
A row is also a read-only mapping of that dict (``row["err_A"]["mean"]``), so
code written for the former plain-dict rows keeps working.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from ..control.timeseries import saturated_steps

if TYPE_CHECKING:
    from ..control.loop_results import ClosedLoops
    from ..control.realized_bound import RealizedBounds
    from .assumptions import Assumptions
    from .stage_results import BitsIdentification, TheoryAtBits

__all__ = ["Stats", "SummaryRow", "build_row", "fit_slope", "json_clean", "summary_row", "UNKNOWN"]


def _num(x: float | None) -> float | None:
    return None if x is None or not np.isfinite(x) else float(x)


def json_clean(obj: Any) -> Any:
    """``obj`` with every NaN/inf float replaced by None and numpy scalars/arrays made plain (recursively)."""
    if isinstance(obj, dict):
        return {k: json_clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_clean(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return json_clean(obj.tolist())
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return _num(float(obj))
    return obj


@dataclass(frozen=True)
class Stats:
    """Mean and standard deviation over the realizations with a finite value (None if there are none)."""

    mean: float | None
    std: float | None

    @classmethod
    def of(cls, x: ArrayLike) -> Stats:
        x = np.asarray(x, dtype=float)
        ok = x[np.isfinite(x)]
        return cls(float(ok.mean()) if ok.size else None, float(ok.std()) if ok.size else None)

    def to_dict(self) -> dict[str, float | None]:
        return {"mean": self.mean, "std": self.std}


@dataclass(frozen=True)
class SummaryRow(Mapping[str, Any]):
    """Summary of one word length (units: errors relative; bounds and norms in state units).

    Attributes
    ----------
    bits : int
    eps_x, eps_u : tuple of float
        Cell widths of the states (n) and inputs (m).
    err_A, err_B : Stats
        Relative Frobenius model errors over realizations.
    err_A_theory, err_B_theory : float or None
        Theorem 1's large-data prediction.
    overload_fraction : float
    bcls_fallbacks, ident_failures : int
    ultimate_bound : float or None
        The letter's delta(eps), from Theorem 1's predicted model errors.
    ultimate_bound_note : str
    rho : float or None
        The rho that bound used (the automatic value unless configured).
    ultimate_bound_realized : dict or None
        ``{"median", "max"}`` of the a-posteriori bound over realizations
        (each realization's own model error and own P); None if not computed.
    realizations, effective_realizations : int
        R, and the number of distinct realizations (1 without dither).
    assumptions : Assumptions or None
        Hypotheses of Theorem 1 and BCLS (:mod:`qsid_core.studies.assumptions`).
    mpc_cost, final_state_norm : dict or None
        Closed-loop summaries (None when MPC is off); ``mpc_cost["mean_bounded"]`` is the mean over
        the loops judged converged or bounded (with the verdicts on).
    qp_steps : int or None
        Closed-loop steps whose input needed the QP solver (a constraint was active).
    saturated_steps : dict or None
        ``{"steps": k, "loops": l, "of_steps": R*steps}``: closed-loop steps with an
        input on its bound, and loops with at least one.
    stabilized_fraction : float or None
        Share of the loops judged ``converged`` on the true plant (:mod:`qsid_core.control.verdicts`).
    closed_loop_outcomes : dict or None
        ``{"converged", "bounded", "diverged", "failed"}`` -> number of loops.
    closed_loop_spectral_radius : dict or None
        ``{"median", "max"}`` of ``max |eig(A - B K^)|`` over the loops with an MPC.
    bound_self_consistent, bound_informative : bool or None
        The letter's delta below rho (else its proof gives no bound) and below ``||x0||``.
    steady_state_error : dict or None
        ``{"mean", "max"}`` over the loops of the RMS of ``||x_t - x_ref||`` over the last
        half of each loop (:attr:`ClosedLoops.steady_state_error`).
    tracking_error : dict or None
        ``{"mean", "max"}`` of the RMS of ``||x_t - r_t||`` over each whole loop.
    controllability : dict or None
        ``{"min_margin", "uncontrollable"}``: the smallest relative singular value of the
        controllability matrix of ``(A^, B^)`` and how many models fall below
        :data:`UNCONTROLLABLE` (the letter's Assumption 2 fails for them).
    """

    bits: int
    eps_x: tuple[float, ...]
    eps_u: tuple[float, ...]
    err_A: Stats
    err_B: Stats
    err_A_theory: float | None
    err_B_theory: float | None
    overload_fraction: float
    bcls_fallbacks: int
    ultimate_bound: float | None
    ultimate_bound_note: str
    ident_failures: int
    realizations: int = 0
    effective_realizations: int = 0
    rho: float | None = None
    ultimate_bound_realized: dict[str, Any] | None = None
    assumptions: Assumptions | None = None
    mpc_cost: dict[str, Any] | None = None
    final_state_norm: dict[str, Any] | None = None
    qp_steps: int | None = None
    saturated_steps: dict[str, Any] | None = None
    stabilized_fraction: float | None = None
    closed_loop_outcomes: dict[str, Any] | None = None
    closed_loop_spectral_radius: dict[str, Any] | None = None
    bound_self_consistent: bool | None = None
    bound_informative: bool | None = None
    controllability: dict[str, Any] | None = None
    steady_state_error: dict[str, Any] | None = None
    tracking_error: dict[str, Any] | None = None
    _dict: dict[str, Any] | None = field(default=None, repr=False, compare=False)

    def to_dict(self) -> dict[str, Any]:
        """Plain strict-JSON data (earlier keys unchanged, new keys added)."""
        if self._dict is None:
            d = {
                "bits": self.bits,
                "eps_x": list(self.eps_x),
                "eps_u": list(self.eps_u),
                "err_A": self.err_A.to_dict(),
                "err_B": self.err_B.to_dict(),
                "err_A_theory": self.err_A_theory,
                "err_B_theory": self.err_B_theory,
                "overload_fraction": self.overload_fraction,
                "bcls_fallbacks": self.bcls_fallbacks,
                "ultimate_bound": self.ultimate_bound,
                "ultimate_bound_note": self.ultimate_bound_note,
                "ident_failures": self.ident_failures,
                "mpc_cost": self.mpc_cost,
                "final_state_norm": self.final_state_norm,
            }
            if self.qp_steps is not None:
                d["qp_steps"] = self.qp_steps
            d.update(
                {
                    "realizations": self.realizations,
                    "effective_realizations": self.effective_realizations,
                    "rho": self.rho,
                    "ultimate_bound_realized": self.ultimate_bound_realized,
                    "assumptions": None if self.assumptions is None else self.assumptions.to_dict(),
                    "saturated_steps": self.saturated_steps,
                    "stabilized_fraction": self.stabilized_fraction,
                    "closed_loop_outcomes": self.closed_loop_outcomes,
                    "closed_loop_spectral_radius": self.closed_loop_spectral_radius,
                    "bound_self_consistent": self.bound_self_consistent,
                    "bound_informative": self.bound_informative,
                    "controllability": self.controllability,
                    "steady_state_error": self.steady_state_error,
                    "tracking_error": self.tracking_error,
                }
            )
            object.__setattr__(self, "_dict", json_clean(d))
        return self._dict or {}  # set just above

    # read-only mapping of to_dict(), for code written for plain-dict rows
    def __getitem__(self, key: str) -> Any:
        return self.to_dict()[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self.to_dict())

    def __len__(self) -> int:
        return len(self.to_dict())


#: The default of an input bound not given (the saturated-steps field is then left out); None would be a value.
UNKNOWN = object()

#: relative smallest singular value of the controllability matrix below which a model counts as uncontrollable
UNCONTROLLABLE = 1e-9


def _loop_verdicts(lp: ClosedLoops) -> dict[str, Any]:
    """The verdict fields of a row from judged closed loops (empty if they were not judged)."""
    counts = lp.outcome_counts()
    if not counts:
        return {}
    rad = np.asarray(lp.spectral_radius, dtype=float)
    rad = rad[np.isfinite(rad)]
    return {
        "stabilized_fraction": counts["converged"] / max(len(lp.outcome), 1),
        "closed_loop_outcomes": counts,
        "closed_loop_spectral_radius": {
            "median": float(np.median(rad)) if rad.size else None,
            "max": float(rad.max()) if rad.size else None,
        },
    }


def _bound_flags(th: TheoryAtBits, realized: RealizedBounds | None) -> dict[str, Any]:
    """Whether the letter's delta (and each a-posteriori delta) is below rho and below ||x0||."""
    ub = getattr(th, "bound", None)
    out: dict[str, Any] = {}
    if ub is not None and np.isfinite(ub.delta):
        out["bound_self_consistent"] = ub.self_consistent
        out["bound_informative"] = ub.informative if np.isfinite(ub.x0_norm) else None
    elif ub is not None or np.isinf(getattr(th, "delta", np.nan)):
        out["bound_self_consistent"], out["bound_informative"] = False, False
    return out


def _loop_fields(lp: ClosedLoops, u_max: Any) -> dict[str, Any]:
    """The closed loops' fields of a :class:`SummaryRow`: cost, final norms, QP steps, errors, saturation
    (when ``u_max`` is known) and verdicts."""
    kw: dict[str, Any] = {}
    failed = lp.failed
    fsn = lp.final_state_norm[~failed]
    kinds: dict[str, int] = {}
    for f in lp.failure:
        if f:
            kinds[f] = kinds.get(f, 0) + 1
    kw["mpc_cost"] = {**Stats.of(lp.cost).to_dict(), "failed": int(failed.sum()), "failures": kinds}
    if lp.outcome:  # the mean over the loops that did not diverge (a diverged loop's cost is no cost)
        kept = np.isin(np.asarray(lp.outcome), ("converged", "bounded"))
        kw["mpc_cost"]["mean_bounded"] = Stats.of(lp.cost[kept]).mean
    kw["final_state_norm"] = {
        "mean": float(fsn.mean()) if fsn.size else None,
        "max": float(fsn.max()) if fsn.size else None,
    }
    kw["qp_steps"] = lp.qp_steps
    for key, vals in (("steady_state_error", lp.steady_state_error), ("tracking_error", lp.tracking_error)):
        ok = vals[np.isfinite(vals)]
        kw[key] = {"mean": float(ok.mean()) if ok.size else None, "max": float(ok.max()) if ok.size else None}
    if u_max is not UNKNOWN:
        k, loops = saturated_steps(lp.inputs, u_max)
        kw["saturated_steps"] = {
            "steps": k,
            "loops": loops,
            "of_steps": int(lp.inputs.shape[0] * lp.inputs.shape[1]),
        }
    kw.update(_loop_verdicts(lp))
    return kw


def build_row(
    n: int,
    ident: BitsIdentification,
    th: TheoryAtBits,
    lp: ClosedLoops | None = None,
    *,
    u_max: Any = UNKNOWN,
    realized: RealizedBounds | None = None,
    assumptions: Assumptions | None = None,
) -> SummaryRow:
    """The :class:`SummaryRow` of one word length.

    Parameters
    ----------
    n : int
        Number of states (splits eps into states and inputs).
    ident, th, lp
        :meth:`Experiment.identification`, :meth:`Experiment.theory` and
        :meth:`Experiment.closed_loops` results (``lp`` None when MPC is off).
    u_max : array_like or None
        Input bounds for the saturated-steps count (None: unbounded, 0 steps);
        when not given, ``saturated_steps`` is None (unknown).
    realized : RealizedBounds, optional
        From :meth:`Experiment.realized_bound`.
    assumptions : Assumptions, optional
        From :meth:`Experiment.assumptions`.
    """
    kw: dict[str, Any] = _loop_fields(lp, u_max) if lp is not None else {}
    kw.update(_bound_flags(th, realized))
    cm = ident.controllability
    cm_ok = cm[np.isfinite(cm)]
    kw["controllability"] = {
        "min_margin": float(cm_ok.min()) if cm_ok.size else None,
        "uncontrollable": int(np.sum(cm_ok < UNCONTROLLABLE)),
    }
    realized_d = None
    if realized is not None:
        realized_d = {
            "median": _num(realized.median),
            "max": _num(realized.max),
            "self_consistent": realized.self_consistent,
            "informative": realized.informative,
        }
    return SummaryRow(
        bits=ident.bits,
        eps_x=tuple(ident.eps[:n].tolist()),
        eps_u=tuple(ident.eps[n:].tolist()),
        err_A=Stats.of(ident.err_A),
        err_B=Stats.of(ident.err_B),
        err_A_theory=_num(th.err_A),
        err_B_theory=_num(th.err_B),
        overload_fraction=float(ident.overload.mean()),
        bcls_fallbacks=int(ident.fallback.sum()),
        ultimate_bound=_num(th.delta),
        ultimate_bound_note=th.bound_note,
        ident_failures=int(ident.failed.sum()),
        realizations=ident.realizations,
        effective_realizations=ident.effective_realizations,
        rho=_num(getattr(th, "rho", float("nan"))),
        ultimate_bound_realized=realized_d,
        assumptions=assumptions,
        **kw,
    )


def fit_slope(bits: ArrayLike, values: ArrayLike) -> float:
    """Least-squares slope of ``log10(values)`` against ``bits`` (NaN if fewer than 2 usable points)."""
    b = np.asarray(bits, dtype=float)
    v = np.asarray(values, dtype=float)
    ok = np.isfinite(v) & (v > 0)
    if ok.sum() < 2:
        return float("nan")
    return float(np.polyfit(b[ok], np.log10(v[ok]), 1)[0])


def summary_row(
    n: int,
    ident: BitsIdentification,
    th: TheoryAtBits,
    lp: ClosedLoops | None,
    *,
    u_max: Any = UNKNOWN,
    realized: RealizedBounds | None = None,
    assumptions: Assumptions | None = None,
) -> SummaryRow:
    """Typed summary of one word length (:class:`~qsid_core.studies.summary.SummaryRow`; ``.to_dict()`` is its JSON).

    Parameters
    ----------
    n : int
        Number of states (splits eps into states and inputs).
    ident, th, lp
        Results of :meth:`Experiment.identification`, :meth:`Experiment.theory` and
        :meth:`Experiment.closed_loops` (``lp`` may be None when MPC is off).
    u_max : array_like or None, optional
        Input bounds, for the count of saturated closed-loop steps.
    realized : RealizedBounds, optional
        The a-posteriori bound (:meth:`Experiment.realized_bound`).
    assumptions : Assumptions, optional
        (:meth:`Experiment.assumptions`).
    """
    return build_row(n, ident, th, lp, u_max=u_max, realized=realized, assumptions=assumptions)
