"""One tab's computation for a nonlinear plant (:func:`iter_koopman_frames`): the engine's
:class:`~qsid_core.studies.Study` of the panel's values (the current b in full, then every other b's models, then
their Koopman MPC loops), its frames arranged for the views (:class:`KoopmanFrame`).

Threads: runs in the tab's worker (see the list in :mod:`app.dashboard.session`); with the server's process pool
the study submits each (b, estimator)'s loops from threads of its own (``qsid-koopman``), abandoned by the
pool's watchdog once newer settings arrive. Every stage is cached in the server's shared cache under the
engine's keys (:func:`qsid_core.studies.koopman_stage_key`): a change recomputes only what depends on it.
"""

from __future__ import annotations

from collections.abc import Callable, Generator, MutableMapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from qsid_core.studies import CancelToken, KoopmanExperiment, KoopmanModels, NonlinearAtBits, Study, StudyFrame

from .koopman_settings import koopman_config
from .settings import LABELS, Values

__all__ = ["KoopmanFrame", "iter_koopman_frames"]


@dataclass
class KoopmanFrame:
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

    @property
    def complete(self) -> bool:
        return self.done >= self.total

    def series(self) -> dict[str, list[dict[str, Any]]]:
        """``{label: [rows sorted by b]}`` for the views."""
        return {lab: [r[b] for b in sorted(r)] for lab, r in self.rows.items()}


def _frame(f: StudyFrame, values: Values) -> KoopmanFrame:
    at = f.at_bits
    assert isinstance(at, NonlinearAtBits) and isinstance(f.experiment, KoopmanExperiment)
    return KoopmanFrame(
        stage="current" if f.stage == "current" else "curves",  # (the models' frame: curves whose loops still run)
        values=values,
        system=f.experiment.system,
        bits=f.bits,
        labels=tuple(LABELS[e] for e in f.estimators),
        rows={LABELS[e]: r for e, r in f.rows.items()},
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
    )


def iter_koopman_frames(
    values: Values,
    cache: MutableMapping[Any, Any] | None = None,
    executor: Any = None,
    tasks: int = 2,
    should_stop: Callable[[], bool] | None = None,
    min_interval: float = 0.3,
    on_progress: Callable[[int, int, str], None] | None = None,
) -> Generator[KoopmanFrame, None, None]:
    """Compute what a tab shows for a nonlinear plant (the engine's :class:`~qsid_core.studies.Study`): a
    "current" frame (the current b in full), a "curves" frame once every b's models are identified, then
    "curves" frames as their loops finish.

    Raises
    ------
    qsid_core.errors.QsidError
        Bad settings (:class:`~app.dashboard.settings.InputError`), a vector field that fails, too few samples.
    """
    cfg, ests = koopman_config(values)
    study = Study(cfg, executor, cache, tasks if executor is not None else 0, tuple(ests))
    for f in study.frames(int(values.bits), CancelToken(should_stop), on_progress, min_interval):
        yield _frame(f, values)
