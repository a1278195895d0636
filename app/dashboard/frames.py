"""What a tab shows at one moment (:class:`Frame`): a frame of the engine's study
(:class:`qsid_core.studies.StudyFrame`, :func:`app.dashboard.stages.iter_frames`) with the panel's values and
labels, arranged for the views (:mod:`app.figures`). No computation here.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from qsid_core import ClosedLoops, DataLengthResult, Experiment, LTISystem
from qsid_core.studies import BitsIdentification, TheoryAtBits, full_row

from .settings import Values

__all__ = ["Frame", "full_row", "row"]

#: Summary rows per estimator label and word length: ``{label: {b: row dict}}``.
Rows = dict[str, dict[int, dict[str, Any]]]


def row(r: Any) -> dict[str, Any]:
    """One engine summary row as the JSON-ready dict the views read (``to_dict()`` of a typed row)."""
    return r.to_dict() if hasattr(r, "to_dict") else dict(r)


@dataclass
class Frame:
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

    @property
    def complete(self) -> bool:
        return self.done >= self.total

    def series(self) -> dict[str, list[dict[str, Any]]]:
        """``{label: [rows sorted by b]}`` for :mod:`app.figures`."""
        return {lab: [r[b] for b in sorted(r)] for lab, r in self.rows.items()}

    @property
    def true_cost(self) -> float | None:
        if self.true_loop is None:
            return None
        c = float(self.true_loop.cost[0])
        return c if np.isfinite(c) else None
