"""What a tab shows at one moment (:class:`Frame`), and the engine calls that fill it (no threads here).

:func:`app.dashboard.session.iter_frames` calls :func:`start` once (the current b
in full), then :func:`fill_rows` chunk by chunk for the other word lengths. All
numbers come from :class:`qsid_core.studies.experiment.Experiment`; this module only
arranges them for the views (:mod:`app.figures`).
"""

from __future__ import annotations

import weakref
from collections.abc import Callable, Iterable, Mapping, MutableMapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from qsid_core import ClosedLoops, DataLengthResult, Experiment, LTISystem, summary_row
from qsid_core.studies import BitsIdentification, TheoryAtBits

from .settings import LABELS, Values, estimators, mpc_config, resolve_system, sweep_config

__all__ = ["Frame", "Job", "start", "fill_rows", "row"]

#: Summary rows per estimator label and word length: ``{label: {b: row dict}}``.
Rows = dict[str, dict[int, dict[str, Any]]]


def row(r: Any) -> dict[str, Any]:
    """One engine summary row as the JSON-ready dict the views read (``to_dict()`` of a typed row)."""
    return r.to_dict() if hasattr(r, "to_dict") else dict(r)


def full_row(
    ex: Experiment, est: str, b: int, lp: ClosedLoops, memo: MutableMapping[Any, Any] | None = None
) -> dict[str, Any]:
    """The engine's complete row at ``b`` (closed loops ``lp``, the a-posteriori bound, the assumptions,
    the saturated steps), as the dict the views read (read-only: it may be reused).

    With ``memo`` (one tab's own mapping, ``(est, b)`` -> the row and what it was built from), a row
    built from the very same result objects is reused: a word-length change redraws every b's row
    from cached results, and building them again was ~30 % of its CPU time. The entry holds weak
    references to those objects and is used only if each still *is* the object passed now.
    """
    mpc = ex.config.mpc
    assert mpc is not None, "the dashboard's experiments always have an MPC"
    parts = (ex.identification(b, est), ex.theory(b), lp, ex.realized_bound(b, est), ex.assumptions(b))
    held = memo.get((est, b)) if memo is not None else None
    if held is not None and all(r() is p for r, p in zip(held[0], parts)):
        return held[1]
    ident, th, _, realized, assumptions = parts
    out = row(
        summary_row(
            ex.system.n,
            ident,
            th,
            lp,
            u_max=mpc.resolve(ex.system).u_max,
            realized=realized,
            assumptions=assumptions,
        )
    )
    if memo is not None:
        try:
            memo[(est, b)] = (tuple(weakref.ref(p) for p in parts), out)
        except TypeError:  # a result type without weak references: not reused
            pass
    return out


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


@dataclass
class Job:
    """One computation for a tab: the engine experiment and what the frames share."""

    ex: Experiment
    estimators: tuple[str, ...]
    bits: int
    all_bits: tuple[int, ...]
    common: dict[str, Any]  # Frame fields that stay fixed while the curves fill
    memo: MutableMapping[Any, Any] | None = None  # the tab's rows, reused when built from the same results

    @property
    def n(self) -> int:
        return self.common["system"].n


def start(
    values: Values,
    cache: MutableMapping[Any, Any] | None,
    executor: Any,
    tasks: int,
    memo: MutableMapping[Any, Any] | None = None,
    quantized: Callable[[Experiment], None] | None = None,
) -> tuple[Job, Rows]:
    """Resolve ``values`` and compute the current b in full; returns the job and its rows {label: {b: row}}.

    ``quantized(ex)``, if given, is called once the current b is quantized (before its models, loops and
    bounds), e.g. to start quantizing the other word lengths meanwhile.

    Raises
    ------
    qsid_core.errors.QsidError
        Bad settings (:class:`~app.dashboard.settings.InputError`), data overflow, ... in plain words.
    """
    choice = resolve_system(values)
    system = choice.system
    cfg = sweep_config(values, system)
    ests = estimators(values.identification)
    ex = Experiment(cfg, executor=executor, tasks=tasks, cache=cache)
    b = int(values.bits)
    if quantized is not None:
        ex.moments([b])
        quantized(ex)
    idents = {LABELS[e]: ex.identification(b, e) for e in ests}
    th = ex.theory(b)
    loops = {LABELS[e]: ex.closed_loops(b, e) for e in ests}
    rows = {LABELS[e]: {b: full_row(ex, e, b, loops[LABELS[e]], memo)} for e in ests}
    mc = mpc_config(values, system)
    x0 = np.asarray(mc.x0 if mc.x0 is not None else system.x0, dtype=float)
    common = dict(
        values=values,
        system=system,
        bits=b,
        labels=tuple(LABELS[e] for e in ests),
        loops=loops,
        true_loop=ex.true_model_loop(),
        theory=th,
        idents=idents,
        x0=x0,
        notes=tuple(choice.notes),
    )
    return Job(ex, ests, b, cfg.bits, common, memo), rows


def fill_rows(
    job: Job, rows: Rows, est: str, bits: Iterable[int], loops: Mapping[int, ClosedLoops] | None = None
) -> None:
    """Add the summary rows of ``est`` at ``bits`` to ``rows`` (closed loops from ``loops`` or computed here)."""
    ex = job.ex
    for x in bits:
        lp = loops[x] if loops is not None else ex.closed_loops(x, est)
        rows[LABELS[est]][x] = full_row(ex, est, x, lp, job.memo)


def make_frame(job: Job, stage: str, rows: Rows, done: int, elapsed: float, timings: dict[str, float]) -> Frame:
    """A frame with a copy of ``rows`` (the caller keeps filling its own)."""
    return Frame(
        stage,
        rows={lab: dict(r) for lab, r in rows.items()},
        done=done,
        total=len(job.all_bits),
        elapsed=elapsed,
        timings=dict(timings),
        ex=job.ex,
        **job.common,
    )
