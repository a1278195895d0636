"""Per-realization results as a tidy table: one row per (b, estimator, realization).

The summary JSON keeps mean/std per word length; researchers doing their own
statistics need every realization. :func:`realization_records` turns a
:class:`~qsid_core.studies.sweep_result.SweepResult` into a list of :class:`RealizationRecord`;
:func:`experiment_records` does the same for several estimators of one
:class:`~qsid_core.studies.experiment.Experiment` (LS and BCLS on the same quantized data).
The table leaves as plain columns (:func:`to_columns`), a CSV file
(:func:`write_csv`, standard library only) or a pandas DataFrame
(:func:`to_pandas`, only if pandas is installed: it is not a dependency).

Missing values (no MPC, failed identification or loop) are NaN in the records
and empty cells in the CSV.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterable
from dataclasses import astuple, dataclass, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeAlias, cast

import numpy as np

from ..errors import ConfigError, check_choice
from ..identification.identify import ESTIMATORS
from .outputs import replace_atomically

if TYPE_CHECKING:
    from ..control.loop_results import ClosedLoops
    from .experiment import Experiment, Progress
    from .stage_results import BitsIdentification
    from .sweep_result import SweepResult

    #: What the table functions take: a finished sweep or a list of records.
    Records: TypeAlias = "SweepResult | Iterable[RealizationRecord]"

__all__ = [
    "RealizationRecord",
    "COLUMNS",
    "realization_records",
    "experiment_records",
    "to_columns",
    "to_pandas",
    "write_csv",
]


@dataclass(frozen=True)
class RealizationRecord:
    """One realization's results at one word length with one estimator.

    Attributes
    ----------
    system : str
    bits : int
    estimator : str
        ``"ls"`` or ``"bcls"``.
    realization : int
        Index r of the dither stream ``SeedSequence(dither_seed).spawn(R)[r]``.
    err_A, err_B : float
        Relative Frobenius errors ``||A^-A||_F/||A||_F``, ``||B^-B||_F/||B||_F`` (NaN if identification failed).
    overload : float
        Fraction of quantized samples that fell outside the quantizer range (0..1).
    ident_failed : bool
        Identification impossible (singular Psi Psi^T).
    bcls_fallback : bool
        BCLS fell back to LS for this realization.
    mpc_status : str
        ``"ok"``, a failure kind of :data:`qsid_core.control.mpc.FAILURE_KINDS` (``"ident"``,
        ``"dare"``, ``"infeasible"``, ...), or ``"off"`` when the sweep ran without MPC.
    mpc_cost : float
        Realised closed-loop cost on the true system (NaN if failed or off).
    mpc_predicted_cost : float
        ``J*(x0)`` the MPC predicted with its own model (NaN if failed or off).
    final_state_norm : float
        ``||x_T||_2`` at the end of the closed loop (NaN if failed or off).
    outcome : str
        The loop's verdict on the true plant: ``"converged"``, ``"bounded"``, ``"diverged"``,
        ``"failed"`` (:mod:`qsid_core.control.verdicts`), or ``"off"`` without MPC or verdicts.
    closed_loop_spectral_radius : float
        ``max |eig(A - B K^)|`` of the MPC's unconstrained law on the true plant (NaN if no MPC).
    controllability : float
        Relative smallest singular value of the controllability matrix of ``(A^, B^)``
        (0: uncontrollable; the letter's Assumption 2), NaN if identification failed.
    """

    system: str
    bits: int
    estimator: str
    realization: int
    err_A: float
    err_B: float
    overload: float
    ident_failed: bool
    bcls_fallback: bool
    mpc_status: str
    mpc_cost: float
    mpc_predicted_cost: float
    final_state_norm: float
    outcome: str = "off"
    closed_loop_spectral_radius: float = math.nan
    controllability: float = math.nan


COLUMNS: tuple[str, ...] = tuple(f.name for f in fields(RealizationRecord))


def _rows(system: str, estimator: str, ident: BitsIdentification, loops: ClosedLoops | None) -> list[RealizationRecord]:
    """Records of one (b, estimator): ``ident`` a BitsIdentification, ``loops`` ClosedLoops or None."""
    R = len(ident.err_A)
    if loops is not None:
        fsn = loops.final_state_norm
        if len(loops.cost) != R:
            raise ConfigError(f"closed loops ({len(loops.cost)}) and realizations ({R}) disagree at b={ident.bits}")
    out = []
    ctrb = ident.controllability
    for r in range(R):
        outcome, radius = "off", math.nan
        if loops is None:
            status, cost, j0, norm = "off", math.nan, math.nan, math.nan
        else:
            status = loops.failure[r] or "ok"
            cost, j0, norm = float(loops.cost[r]), float(loops.J0[r]), float(fsn[r])
            if loops.outcome and loops.spectral_radius is not None:  # judged: both are filled
                outcome, radius = loops.outcome[r], float(loops.spectral_radius[r])
        out.append(
            RealizationRecord(
                system,
                int(ident.bits),
                estimator,
                r,
                float(ident.err_A[r]),
                float(ident.err_B[r]),
                float(ident.overload[r]),
                bool(ident.failed[r]),
                bool(ident.fallback[r]),
                status,
                cost,
                j0,
                norm,
                outcome,
                radius,
                float(ctrb[r]),
            )
        )
    return out


def realization_records(result: SweepResult) -> list[RealizationRecord]:
    """One record per (b, realization) of a finished sweep (its estimator), ordered by b then realization.

    Parameters
    ----------
    result : SweepResult

    Returns
    -------
    list of RealizationRecord, length ``len(result.bits) * result.config.realizations``
    """
    est = result.config.estimator
    name = result.system.name
    out: list[RealizationRecord] = []
    for b in result.bits:
        out.extend(_rows(name, est, result.identification[b], result.loops.get(b)))
    return out


def experiment_records(
    experiment: Experiment,
    bits: str | int | list[int] | tuple[int, ...] | range,
    estimators: Iterable[str] = ESTIMATORS,
    progress: Progress | None = None,
) -> list[RealizationRecord]:
    """Records for several estimators on the same quantized data (MPC loops included when configured).

    Parameters
    ----------
    experiment : Experiment
        Its caches are used and filled (moments are computed once for all estimators).
    bits : spec of word lengths (see :func:`qsid_core.studies.experiment.parse_bits`)
    estimators : iterable of {"ls", "bcls"}
    progress : callable(done, total, stage), optional

    Returns
    -------
    list of RealizationRecord ordered by estimator, b, realization
    """
    from .config import parse_bits

    bits = parse_bits(bits)
    ests = [check_choice("estimator", e, ESTIMATORS) for e in estimators]
    if not ests:
        raise ConfigError("estimators: give at least one of " + ", ".join(ESTIMATORS))
    experiment.moments(bits, progress)
    out: list[RealizationRecord] = []
    for est in ests:
        loops = experiment.closed_loops_many(bits, est, progress) if experiment.config.mpc is not None else {}
        for b in bits:
            out.extend(_rows(experiment.system.name, est, experiment.identification(b, est), loops.get(b)))
    return out


def _records(obj: Records) -> list[RealizationRecord]:
    if hasattr(obj, "identification") and hasattr(obj, "bits"):
        return realization_records(cast("SweepResult", obj))
    recs = list(obj)
    if not all(isinstance(r, RealizationRecord) for r in recs):
        raise ConfigError("expected a SweepResult or a list of RealizationRecord")
    return recs


def to_columns(records_or_result: Records) -> dict[str, list[Any]]:
    """The table as ``{column: list of values}`` (plain Python, no dependencies)."""
    recs = _records(records_or_result)
    return {c: [getattr(r, c) for r in recs] for c in COLUMNS}


def to_pandas(records_or_result: Records) -> Any:
    """The table as a ``pandas.DataFrame`` (columns :data:`COLUMNS`).

    Raises
    ------
    ImportError
        If pandas is not installed (use :func:`to_columns` or :func:`write_csv` instead).
    """
    try:
        import pandas as pd
    except ImportError:
        raise ImportError(
            "to_pandas needs pandas (pip install pandas); without it use qsid_core.studies.records.to_columns or write_csv"
        ) from None
    return pd.DataFrame(to_columns(records_or_result), columns=list(COLUMNS))


def _cell(v: object) -> str:
    if isinstance(v, (bool, np.bool_)):
        return "true" if v else "false"
    if isinstance(v, float):
        return "" if math.isnan(v) else repr(v)
    return str(v)


def write_csv(records_or_result: Records, path: str | Path) -> int:
    """Write the tidy table to ``path`` (header :data:`COLUMNS`, NaN as an empty cell); returns the row count.

    Floats are written with ``repr`` (they read back bit-exactly); booleans as ``true``/``false``.
    The file is written whole or not at all: into a temporary file in the same directory, renamed over
    ``path`` when complete (an existing ``path`` stays as it was until then; the temporary file is removed
    if the write fails or is interrupted).
    """
    recs = _records(records_or_result)
    buf = io.StringIO(newline="")
    w = csv.writer(buf)
    w.writerow(COLUMNS)
    for r in recs:
        w.writerow([_cell(v) for v in astuple(r)])
    replace_atomically(Path(path), buf.getvalue())
    return len(recs)
