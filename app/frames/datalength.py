"""The data-length study of a tab, on demand, in one background thread (mechanism (9) of :mod:`app.dashboard.session`).

The study (:func:`qsid_core.studies.datalength.run_datalength`) simulates up to 10^6
samples per realization, seconds to a minute: it runs only when the person
presses its button, in its own thread and in-process (not in the shared process
pool, so the other views and tabs never wait behind it), one realization per
task so a new change cancels it within about a second. A finished study is kept
in the shared cache under its settings, so any tab with the same settings (and a
b already computed) shows it at once.

Its settings are the tab's sweep's (:meth:`~qsid_core.DataLengthConfig.from_sweep`: system, data seed and
amplitudes, quantizer, sensor noise, word length per channel, dither seed) at the tab's b, and its cache key is
the engine's (:func:`~qsid_core.studies.datalength_key`, generated from the config's fields).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, MutableMapping
from typing import cast

from app.settings.config import study_config, sweep_config
from app.settings.values import Values, is_nonlinear, resolve_system
from qsid_core import DataLengthConfig, DataLengthResult, SweepConfig, get_system, run_datalength
from qsid_core.studies import DEFAULT_SAMPLES, datalength_key

__all__ = ["DataLengthRunner", "datalength_config", "MAX_REALIZATIONS"]

#: Realizations of the study (the panel's, at most this many: 10 x 10^6 samples is ~15 s on one core).
MAX_REALIZATIONS = 10


def datalength_config(values: Values) -> DataLengthConfig:
    """The study of the panel's sweep (:func:`~app.settings.config.sweep_config`) at its current b: ten lengths,
    10^3..10^6 samples, at most :data:`MAX_REALIZATIONS` realizations."""
    if is_nonlinear(values.system):  # (its panel's linear stand-in)
        sweep = sweep_config(values, resolve_system(values).system)
    else:  # the tab's own configuration (made once per values)
        sweep = cast(SweepConfig, study_config(values).config)
    return DataLengthConfig.from_sweep(
        sweep,
        bits=int(values.bits),
        samples=DEFAULT_SAMPLES,
        realizations=min(sweep.realizations, MAX_REALIZATIONS),
    )


def _key(cfg: DataLengthConfig) -> tuple:
    return datalength_key(cfg, get_system(cfg.system))


class DataLengthRunner:
    """At most one data-length study per tab, in its own thread (``thread``).

    Parameters
    ----------
    cache : mapping
        The shared cache (finished studies are stored there).
    on_progress : callable(fraction 0..1, text)
        Progress and outcome in plain words (called from the study's thread).
    on_done : callable()
        A study finished: the tab redraws (its frame then finds the result in the cache).
    """

    def __init__(self, cache: MutableMapping, on_progress: Callable[[float, str], None], on_done: Callable[[], None]):
        self.cache = cache
        self.on_progress = on_progress
        self.on_done = on_done
        self.thread: threading.Thread | None = None

    def lookup(self, values: Values) -> DataLengthResult | None:
        """The finished study for ``values``, if any (None for settings that cannot be resolved)."""
        try:
            return self.cache.get(_key(datalength_config(values)))
        except Exception:  # bad settings: the tab shows the error elsewhere
            return None

    @property
    def running(self) -> bool:
        return self.thread is not None and self.thread.is_alive()

    def start(self, values: Values, stale: Callable[[], bool]) -> bool:
        """Start the study for ``values`` unless one runs; ``stale()`` true (a newer change) cancels it."""
        if self.running:
            return False
        try:
            cfg = datalength_config(values)
        except ValueError as exc:  # settings the engine refuses (an InputError): said in the tab, in one line
            self.on_progress(0.0, f"⚠️ data-length study: {exc}")
            return False
        if self.cache.get(_key(cfg)) is not None:
            self.on_done()
            return True
        self.thread = threading.Thread(target=self._run, args=(cfg, stale), name="qsid-datalength", daemon=True)
        self.thread.start()
        return True

    def _run(self, cfg: DataLengthConfig, stale: Callable[[], bool]) -> None:
        def progress(done: int, total: int, text: str) -> None:
            self.on_progress(done / total, f"computing {done}/{total}: {text}")

        try:
            res = run_datalength(cfg, None, progress, should_stop=stale, tasks=cfg.realizations)
        except Exception as exc:  # shown in the tab; the thread ends cleanly
            self.on_progress(0.0, f"⚠️ data-length study failed: {type(exc).__name__}: {exc}")
            return
        if res.cancelled:
            self.on_progress(
                0.0,
                f"cancelled by a change after {len(res.rows)} of {len(cfg.samples)} lengths; press the button again",
            )
            return
        self.cache[_key(cfg)] = res
        self.on_progress(1.0, f"done: {len(res.rows)} lengths, {cfg.realizations} realizations, b = {cfg.bits}")
        self.on_done()
