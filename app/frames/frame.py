"""What a front end shows at one moment: a frame of the engine's study (:class:`qsid_core.studies.StudyFrame`,
:func:`app.frames.compute.iter_frames`) with the panel's values and labels, arranged for the views
(:mod:`app.figures`): :class:`Frame` for a linear plant, :class:`KoopmanFrame` for a nonlinear one
(:func:`tab_frame` makes either from the study's, by what its result holds; :func:`lifted` tells them apart).
No computation here.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from app.settings.values import LABELS, Values
from qsid_core import ClosedLoops, DataLengthResult, Experiment, LTISystem
from qsid_core.studies import (
    BitsIdentification,
    KoopmanExperiment,
    KoopmanModels,
    LinearAtBits,
    NonlinearAtBits,
    StudyFrame,
    TheoryAtBits,
    full_row,
)

__all__ = ["Frame", "KoopmanFrame", "full_row", "lifted", "row", "tab_frame"]

#: Summary rows per estimator label and word length: ``{label: {b: row dict}}``.
Rows = dict[str, dict[int, dict[str, Any]]]


def row(r: Any) -> dict[str, Any]:
    """One engine summary row as the JSON-ready dict the views read (``to_dict()`` of a typed row)."""
    return r.to_dict() if hasattr(r, "to_dict") else dict(r)


class _Rows:
    """What both kinds of frame answer from their word lengths done and their rows by estimator label."""

    done: int
    total: int
    rows: Rows

    @property
    def complete(self) -> bool:
        return self.done >= self.total

    def series(self) -> dict[str, list[dict[str, Any]]]:
        """``{label: [rows sorted by b]}`` for :mod:`app.figures`."""
        return {lab: [r[b] for b in sorted(r)] for lab, r in self.rows.items()}


@dataclass
class Frame(_Rows):
    """One drawable state of a tab: the current b in full, and the rows of every b computed so far.

    Attributes
    ----------
    stage : {"current", "curves"}
        ``"current"``: the current b just finished; ``"curves"``: more word lengths filled.
    values : Values
        The panel values this frame was computed for.
    system : LTISystem
    bits : int
        The current word length (drawn in 3-D).
    labels : tuple of str
        Estimator labels shown (``"LS"``, ``"BCLS"``).
    rows : dict label -> {b: summary row dict}
        :func:`qsid_core.studies.summary.summary_row` per estimator label and word length.
    done, total : int
        Word lengths computed so far, of all.
    loops : dict label -> ClosedLoops at the current b
    true_loop : ClosedLoops
        The MPC built on the true model.
    theory : TheoryAtBits at the current b
    idents : dict label -> BitsIdentification at the current b
    x0 : ndarray (n,)
        Start state of every closed loop (state units).
    notes : tuple of str
        Plain-words notes about the system (e.g. not controllable).
    elapsed : float
        Seconds since the change that started this computation.
    ex : Experiment
        The engine's experiment (its cache holds every b computed so far).
    pinned : Frame or None
        A frame the person pinned for comparison (set by the tab, not computed).
    datalength : DataLengthResult or None
        The data-length study for these settings, if one finished (set by the tab).
    budget : Bandwidth or None
        The budget study of these settings (:func:`qsid_core.studies.bandwidth`), once it finished.
    """

    stage: str
    values: Values
    system: LTISystem
    bits: int
    labels: tuple[str, ...]
    rows: Rows
    done: int
    total: int
    loops: dict[str, ClosedLoops]
    true_loop: ClosedLoops | None
    theory: TheoryAtBits
    idents: dict[str, BitsIdentification]
    x0: NDArray[np.float64]
    notes: tuple[str, ...] = ()
    elapsed: float = 0.0
    timings: dict[str, float] = field(default_factory=dict)
    ex: Experiment | None = None
    pinned: Frame | None = None
    datalength: DataLengthResult | None = None
    budget: Any = None

    @property
    def true_cost(self) -> float | None:
        if self.true_loop is None:
            return None
        c = float(self.true_loop.cost[0])
        return c if np.isfinite(c) else None


@dataclass
class KoopmanFrame(_Rows):
    """One drawable state of a tab showing a nonlinear plant.

    Attributes
    ----------
    stage : {"current", "curves"}
    values : Values
    system : NonlinearSystem
    bits : int
        The current word length (drawn in 3-D, eigenvalues).
    labels : tuple of str
        Estimator labels shown (``"LS"``, ``"BCLS"``).
    rows : dict label -> {b: row}
        The rows of :class:`~qsid_core.studies.KoopmanResult` computed so far (``closed_loop_outcomes`` None for a
        b whose loops are still running).
    done, total : int
        Word lengths whose loops are done, of all.
    models, loops : dict label -> KoopmanModels / KoopmanLoops at the current b
    reference, reference_error, reference_loop : the unquantized EDMD, its prediction error and its loop
    flow : ndarray (k, T+1, n)
        The plant's free flow.
    x0 : ndarray (n,)
    horizon : int
        Samples of the prediction error.
    features : int
    data_report : str
    ex : KoopmanExperiment
    """

    kind: ClassVar[str] = "koopman"
    stage: str
    values: Values
    system: Any
    bits: int
    labels: tuple[str, ...]
    rows: dict[str, dict[int, dict[str, Any]]]
    done: int
    total: int
    models: dict[str, KoopmanModels]
    loops: dict[str, Any]
    reference: Any
    reference_error: float
    reference_loop: Any
    flow: np.ndarray
    x0: np.ndarray
    horizon: int
    features: int
    data_report: str
    ex: KoopmanExperiment | None = None
    elapsed: float = 0.0
    timings: dict[str, float] = field(default_factory=dict)
    pinned: Any = None
    datalength: Any = None
    budget: Any = None


def tab_frame(f: StudyFrame, values: Values, system: Any = None, notes: tuple[str, ...] = ()) -> Frame | KoopmanFrame:
    """The tab's frame of study frame ``f`` for ``values`` (``system`` and ``notes``: the linear plant resolved
    from the panel and what it says about it)."""
    labels = tuple(LABELS[e] for e in f.estimators)
    rows = {LABELS[e]: r for e, r in f.rows.items()}
    at = f.at_bits
    if isinstance(at, LinearAtBits):
        return Frame(
            "curves" if f.stage == "budget" else f.stage,
            values=values,
            system=system,
            bits=f.bits,
            labels=labels,
            rows=rows,
            done=f.done,
            total=f.total,
            loops={LABELS[e]: lp for e, lp in at.loops.items()},
            true_loop=at.true_loop,
            theory=at.theory,
            idents={LABELS[e]: i for e, i in at.idents.items()},
            x0=at.x0,
            notes=notes,
            elapsed=f.elapsed,
            timings=dict(f.timings),
            ex=f.experiment,  # type: ignore[arg-type]
            budget=f.budget,
        )
    assert isinstance(at, NonlinearAtBits) and isinstance(f.experiment, KoopmanExperiment)
    return KoopmanFrame(
        stage="current" if f.stage == "current" else "curves",  # (the models' frame: curves whose loops still run)
        values=values,
        system=f.experiment.system,
        bits=f.bits,
        labels=labels,
        rows=rows,
        done=f.done,
        total=f.total,
        models={LABELS[e]: m for e, m in at.models.items()},
        loops={LABELS[e]: lp for e, lp in at.loops.items()},
        reference=at.reference,
        reference_error=at.reference_error,
        reference_loop=at.reference_loop,
        flow=at.flow,
        x0=at.x0,
        horizon=at.horizon,
        features=at.features,
        data_report=at.data_report,
        ex=f.experiment,
        elapsed=f.elapsed,
        timings=dict(f.timings),
        budget=f.budget,
    )


def lifted(frame: Any) -> bool:
    """Whether ``frame``'s result holds a lifting (a nonlinear plant's EDMD models, :class:`KoopmanFrame`): the
    views, summary and exports that differ between the kinds of plant are chosen by this."""
    return isinstance(frame, KoopmanFrame)
