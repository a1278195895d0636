"""Sweeps over the word length b: identification, theory and MPC, with dither realizations.

For each b, ``realizations`` independent dither realizations quantize the *same*
unquantized data. Realization ``r`` draws its dither from stream ``r`` of
``SeedSequence(dither_seed).spawn(realizations)``, and the same unit draws are
reused for every b (common random numbers: smooth curves, fair comparison
between word lengths).

Independent work is mapped through a :class:`concurrent.futures.Executor`
(default: in-process), so a ``ProcessPoolExecutor`` or a dask.distributed
client's executor can run big sweeps.

Stages are separate so front ends can cache them: :class:`Experiment` keeps the
data, the normalised data and the identified models, and recomputes only what
a change of settings touches.
"""

from __future__ import annotations

import math
from collections.abc import Callable, MutableMapping
from concurrent.futures import Executor
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from ..control.bound import RealizedBounds, realized_bounds, riccati_finite, ultimate_bound
from ..control.closed_loop import run_closed_loops
from ..control.loop_results import ClosedLoops
from ..control.mpc import MPCConfig
from ..control.riccati import dare_stabilizing
from ..errors import ConfigError, MPCFailure, check_choice, check_int
from ..identification.identify import ESTIMATORS, identify, relative_errors
from ..identification.theorem1 import theorem1_prediction
from ..plant.data import Dataset, simulate, with_sensor_noise
from ..plant.lti import LTISystem
from ..plant.systems import get_system
from ..quantization.moments import Moments, PreparedData, prepare, quantized_moments
from ..quantization.quantize import QuantizerSpec
from .config import SweepConfig, parse_bits
from .config_checks import check_run_args
from .executors import InlineExecutor, single_threaded_blas
from .stage_results import BitsIdentification, TheoryAtBits

if TYPE_CHECKING:
    from .assumptions import Assumptions

__all__ = ["Experiment"]

Progress = Callable[[int, int, str], None]


def _moments_task(
    prep: PreparedData, bits: tuple, spec: QuantizerSpec, seeds: list, input_bits=None, state_bits=None
) -> list[list[Moments]]:
    """Quantized moments for a chunk of realizations (module level: picklable for process pools)."""
    out = []
    with single_threaded_blas():
        for ss in seeds:
            rng = np.random.default_rng(ss) if spec.dither != "none" else None
            out.append(quantized_moments(prep, list(bits), spec, rng, input_bits=input_bits, state_bits=state_bits))
    return out


def _loops_task(models, A, B, cfg: MPCConfig, system: LTISystem, feedback_range=None) -> ClosedLoops:
    with single_threaded_blas():
        return run_closed_loops(models, A, B, cfg, system, feedback_range)


class Experiment:
    """Staged, cached computation for one system and data set.

    Parameters
    ----------
    config : SweepConfig
    executor : concurrent.futures.Executor, optional
        Runs independent tasks (default: :class:`InlineExecutor`). If it has a
        ``share(obj)`` method, the data every task needs is passed through it
        once (a cluster sends it once per worker, not with every task).
    tasks : int
        Number of chunks the realizations are split into for the executor.
    cache : MutableMapping, optional
        Where stage results are kept (default: a private dict). Pass one shared,
        bounded mapping to let several experiments (browser tabs) share results.

    Notes
    -----
    Every expensive product is cached by the settings it depends on:
    the data by (trajectories, steps, data seed, input amplitude); the normalised data by the
    quantizer range; moments by (b, dither, dither seed, realizations); models by
    the estimator. :meth:`with_config` returns an experiment for new settings
    that shares every cache entry still valid.
    """

    def __init__(
        self,
        config: SweepConfig,
        executor: Executor | None = None,
        tasks: int = 4,
        cache: MutableMapping | None = None,
    ):
        check_run_args(config, SweepConfig, executor, None)
        self.config = config
        self.system = get_system(config.system)
        self.executor = executor or InlineExecutor()
        self.tasks = check_int("tasks", tasks, 1, 1024)
        # keys start with the system's matrices, so one mapping can serve many experiments
        self._cache: MutableMapping = {} if cache is None else cache

    # ----- caching ----------------------------------------------------------------------
    def with_config(self, config: SweepConfig) -> Experiment:
        """An experiment for ``config`` that reuses this one's still-valid cache entries."""
        return Experiment(config, self.executor, self.tasks, self._cache)

    def _key_data(self):
        c, s = self.config, self.system
        sysk = (s.A.shape, s.B.shape, s.A.tobytes(), s.B.tobytes(), s.x0.tobytes(), s.Q.tobytes(), s.R.tobytes())
        return sysk + (c.trajectories, c.steps, c.data_seed, c.input_amplitude)

    def _key_prep(self):
        q = self.config.quantizer
        return self._key_data() + (q.range_mode, q.guard, q.fixed_range, self.config.noise)

    def _memo(self, key, make):
        """``cache[key]``, or ``make()`` stored there and returned.

        The value is returned from here, never read back: a shared, bounded cache (the dashboard's)
        may drop any entry at any moment while other threads store theirs.
        """
        try:
            return self._cache[key]
        except KeyError:
            pass
        value = make()
        self._cache[key] = value
        return value

    def _cached(self, keys: dict) -> dict:
        """``{b: cache[keys[b]]}`` for the keys the cache holds now."""
        out = {}
        for b, key in keys.items():
            try:
                out[b] = self._cache[key]
            except KeyError:
                pass
        return out

    def _key_mom(self, b):
        c, q = self.config, self.config.quantizer
        return self._key_prep() + (
            b,
            q.dither,
            c.dither_seed,
            c.realizations,
            c.input_bits,
            c.noise_known,
            c.state_bits,
        )

    def _noise_variance(self) -> np.ndarray:
        """Sensor noise variance per channel of ``Psi``, shape (n + m,) (0 for the inputs)."""
        n, m = self.system.n, self.system.m
        s = np.asarray(self.config.noise, dtype=float)
        if s.size not in (1, n):
            raise ConfigError(f"noise has {s.size} values; give one for every state or one per state ({n})")
        return np.concatenate([np.broadcast_to(s**2, (n,)), np.zeros(m)])

    @property
    def data(self) -> Dataset:
        """The unquantized data set (simulated once)."""
        c = self.config
        return self._memo(
            ("data",) + self._key_data(),
            lambda: simulate(self.system, c.trajectories, c.steps, c.data_seed, c.input_amplitude),
        )

    @property
    def prepared(self) -> PreparedData:
        """The recorded data (with sensor noise, if any) normalised to the quantizer ranges.

        Its ``exact`` moments are those of the noise-free data (Theorem 1's ``Sigma``).
        """
        return self._memo(("prep",) + self._key_prep(), self._prepare)

    def _prepare(self) -> PreparedData:
        c = self.config
        if any(v > 0 for v in c.noise):
            self._noise_variance()  # wrong number of values: one clear error
            rec = with_sensor_noise(self.data, c.noise, c.data_seed)
            return replace(prepare(rec, c.quantizer), exact=prepare(self.data, c.quantizer).exact)
        return prepare(self.data, c.quantizer)

    @property
    def Sigma(self) -> np.ndarray:
        """``Psi_uqz Psi_uqz^T / T`` of the unquantized data."""
        ex = self.prepared.exact
        return ex.PP / ex.T

    # ----- identification --------------------------------------------------------------
    def moments(self, bits, progress: Progress | None = None) -> dict[int, list[Moments]]:
        """Quantized Gram matrices per b and realization (computes only what is not cached)."""
        bits = parse_bits(bits)
        keys = {b: ("mom",) + self._key_mom(b) for b in bits}
        out = self._cached(keys)
        todo = tuple(b for b in bits if b not in out)
        if todo:
            c = self.config
            prep = self.prepared
            seeds = np.random.SeedSequence(c.dither_seed).spawn(c.realizations)
            nt = min(self.tasks, c.realizations)
            size = math.ceil(c.realizations / nt)
            chunks = [seeds[i : i + size] for i in range(0, c.realizations, size)]
            # an executor with a ``share`` hook (e.g. app.distributed.DaskExecutor) sends the data once per worker
            share = getattr(self.executor, "share", None)
            prep_arg = share(prep) if callable(share) else prep
            futs = [
                self.executor.submit(_moments_task, prep_arg, todo, c.quantizer, ch, c.input_bits, c.state_bits)
                for ch in chunks
            ]
            per_real: list[list[Moments]] = []
            for i, f in enumerate(futs):
                per_real.extend(f.result())
                if progress:
                    progress(i + 1, len(futs), "quantize + identify")
            for j, b in enumerate(todo):
                out[b] = [pr[j] for pr in per_real]
                self._cache[keys[b]] = out[b]
        return {b: out[b] for b in bits}

    def identification(self, b: int, estimator: str | None = None) -> BitsIdentification:
        """Identified models at word length ``b`` for every realization."""
        est = estimator or self.config.estimator
        check_choice("estimator", est, ESTIMATORS)
        return self._memo(("ident", est) + self._key_mom(b), lambda: self._identify(b, est))

    def _identify(self, b: int, est: str) -> BitsIdentification:
        moms = self.moments([b])[b]
        if self.config.noise_known and any(v > 0 for v in self.config.noise):
            extra = self._noise_variance()
            moms = [replace(mo, D=mo.noise_variance + extra) for mo in moms]
        sysA, sysB = self.system.A, self.system.B
        n, m = sysB.shape
        ids: list = []
        notes: set = set()
        for mo in moms:
            try:
                ids.append(identify(mo, est))
            except ValueError as exc:  # singular data of one realization: record, don't abort
                ids.append(None)
                notes.add(f"identification failed: {exc}")
        nan_A, nan_B = np.full((n, n), np.nan), np.full((n, m), np.nan)
        A_hat = np.stack([i.A if i is not None else nan_A for i in ids])
        B_hat = np.stack([i.B if i is not None else nan_B for i in ids])
        errs = np.array([relative_errors(a, bm, sysA, sysB) for a, bm in zip(A_hat, B_hat)])
        notes |= {i.note for i in ids if i is not None and i.note}
        return BitsIdentification(
            bits=b,
            eps=moms[0].eps,
            A_hat=A_hat,
            B_hat=B_hat,
            err_A=errs[:, 0],
            err_B=errs[:, 1],
            overload=np.array([mo.overload_fraction for mo in moms]),
            fallback=np.array([i is not None and i.fallback for i in ids]),
            notes=sorted(notes),
            failed=np.array([i is None for i in ids]),
            dither=self.config.quantizer.dither,
        )

    # ----- theory ----------------------------------------------------------------------
    def theory(self, b: int) -> TheoryAtBits:
        """Theorem 1 prediction and the ultimate bound delta(eps) at word length ``b``."""
        c = self.config
        mcfg = c.mpc or MPCConfig()
        k = (
            "theory",
            b,
            c.theta,
            c.rho,
            mcfg.horizon,
            mcfg.Q,
            mcfg.R,
            mcfg.Qf,
            mcfg.x0,
            c.quantizer.dither,
            c.input_bits,
            c.state_bits,
        ) + self._key_prep()
        return self._memo(k, lambda: self._theory(b))

    def _theory(self, b: int) -> TheoryAtBits:
        from ..quantization.quantize import channel_bits, channel_eps

        c = self.config
        mcfg = c.mpc or MPCConfig()
        prep = self.prepared
        sysm = self.system
        n = sysm.n
        q = c.quantizer
        chan = channel_bits(b, n, sysm.m, c.input_bits, c.state_bits)
        eps = channel_eps(prep.lo, prep.hi, chan, q.guard, q.dither)
        # the LS limit with white sensor noise on the states: Sigma (noise-free) + D + sigma^2
        Gp = theorem1_prediction(sysm.G, self.Sigma, eps, q.dither, self._noise_variance())
        eA, eB = relative_errors(Gp[:, :n], Gp[:, n:], sysm.A, sysm.B)
        w = mcfg.resolve(sysm)
        note, ub = "", None
        try:
            Qf = w.Qf if w.Qf is not None else dare_stabilizing(Gp[:, :n], Gp[:, n:], w.Q, w.R)
            P = riccati_finite(Gp[:, :n], Gp[:, n:], w.Q, w.R, Qf, mcfg.horizon)
            ub = ultimate_bound(P, w.Q, w.R, sysm.A - Gp[:, :n], sysm.B - Gp[:, n:], theta=c.theta, rho=c.rho, x0=w.x0)
            delta = ub.delta
            note = ub.note
        except MPCFailure as exc:
            delta, note = float("inf"), str(exc)
        except np.linalg.LinAlgError:
            delta, note = float("inf"), "no bound: the Riccati recursion of the predicted model is singular"
        except ConfigError as exc:
            delta, note = float("nan"), str(exc)
        return TheoryAtBits(b, Gp, eA, eB, delta, note, ub)

    def realized_bound(self, b: int, estimator: str | None = None) -> RealizedBounds:
        """A-posteriori ultimate bound per realization at ``b``: its own model error and its own ``P``.

        See :func:`qsid_core.control.bound.realized_bounds`; the MPC settings are the
        config's (or the defaults when MPC is off).
        """
        c = self.config
        mcfg = c.mpc or MPCConfig()
        est = estimator or c.estimator
        k = ("realized-bound", est, c.theta, c.rho, mcfg.horizon, mcfg.Q, mcfg.R, mcfg.Qf, mcfg.x0) + self._key_mom(b)

        def make() -> RealizedBounds:
            w = mcfg.resolve(self.system)
            with single_threaded_blas():
                return realized_bounds(
                    self.identification(b, est).models,
                    self.system.A,
                    self.system.B,
                    w.Q,
                    w.R,
                    w.Qf,
                    mcfg.horizon,
                    theta=c.theta,
                    rho=c.rho,
                    x0=w.x0,
                )

        return self._memo(k, make)

    def overload_effect(self, b: int) -> np.ndarray:
        """Predicted change of ``[A^, B^]`` caused by the quantizer clipping the data at ``b``, shape (n, n+m)
        (zeros when nothing clips; :func:`qsid_core.studies.assumptions.overload_effect`). Needs no quantized data, so
        it can be computed while the data are being quantized."""
        from .assumptions import overload_effect

        c = self.config
        k = ("overload-effect", b, c.quantizer.dither, c.input_bits, c.state_bits) + self._key_prep()
        return self._memo(k, lambda: overload_effect(self, b))

    def assumptions(self, b: int) -> Assumptions:
        """Which hypotheses of Theorem 1 and of BCLS hold at ``b`` (see :mod:`qsid_core.studies.assumptions`)."""
        from .assumptions import assess

        return self._memo(("assumptions",) + self._key_mom(b), lambda: assess(self, b))

    # ----- MPC -------------------------------------------------------------------------
    def feedback_range(self) -> tuple | None:
        """``(lo, hi, guard)`` of the training data's states, for a quantized measurement in the loop (else None)."""
        cfg = self.config.mpc
        if cfg is None or cfg.feedback_bits is None:
            return None
        prep = self.prepared
        return prep.lo, prep.hi, self.config.quantizer.guard

    def closed_loops(self, b: int, estimator: str | None = None) -> ClosedLoops:
        """Closed loops on the true system of the MPC built on each realization's model at ``b``."""
        cfg = self.config.mpc
        if cfg is None:
            raise ConfigError("this experiment has MPC switched off (mpc=None)")
        est = estimator or self.config.estimator
        return self._memo(
            ("loops", est, cfg) + self._key_mom(b), lambda: run_closed_loops(*self._loop_args(b, est, cfg))
        )

    def _loop_args(self, b: int, est: str, cfg: MPCConfig) -> tuple:
        """``run_closed_loops``' arguments for the models identified by ``est`` at ``b``."""
        return (
            self.identification(b, est).models,
            self.system.A,
            self.system.B,
            cfg,
            self.system,
            self.feedback_range(),
        )

    def closed_loops_many(self, bits, estimator: str | None = None, progress: Progress | None = None) -> dict:
        """:meth:`closed_loops` for several b, mapped through the executor."""
        cfg = self.config.mpc
        if cfg is None:
            raise ConfigError("this experiment has MPC switched off (mpc=None)")
        est = estimator or self.config.estimator
        bits = parse_bits(bits)
        keys = {b: ("loops", est, cfg) + self._key_mom(b) for b in bits}
        out = self._cached(keys)
        todo = [b for b in bits if b not in out]
        futs = {b: self.executor.submit(_loops_task, *self._loop_args(b, est, cfg)) for b in todo}
        for i, (b, f) in enumerate(futs.items()):
            out[b] = f.result()
            self._cache[keys[b]] = out[b]
            if progress:
                progress(i + 1, len(futs), "MPC closed loops")
        return {b: out[b] for b in bits}

    def true_model_loop(self) -> ClosedLoops:
        """The MPC built on the true (A, B): the reference every quantized model is compared to."""
        cfg = self.config.mpc
        if cfg is None:
            raise ConfigError("this experiment has MPC switched off (mpc=None)")
        k = ("true-loop", cfg) + (self._key_prep() if cfg.feedback_bits is not None else self._key_data()[:7])
        return self._memo(
            k,
            lambda: run_closed_loops(
                [(self.system.A, self.system.B)], self.system.A, self.system.B, cfg, self.system, self.feedback_range()
            ),
        )
