"""What every ``qsid`` command that computes shares: progress on stderr, the engine config from the
arguments, the executor, and :func:`run` (the sweep plus optional extra closed loops).

Commands import this module (and :mod:`app.cli.output`), never each other.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import shutil
import sys
import threading
import time
import warnings
from collections.abc import Iterator, Sequence
from concurrent.futures import Executor, ThreadPoolExecutor
from typing import TYPE_CHECKING, Any, Protocol, TextIO

from app.stop import check_stopped

from .mpc_args import mpc_config
from .parser import PROG, UsageError

if TYPE_CHECKING:
    from qsid_core import DataLengthConfig, Experiment, LTISystem, QuantizerSpec, SweepConfig, SweepResult

__all__ = [
    "UsageError",
    "Reporter",
    "one_line",
    "resolve_system",
    "quantizer_from_args",
    "system_from_args",
    "config",
    "workers",
    "run",
    "bits_text",
]


class Channels(Protocol):
    """What :func:`quantizer_from_args` reads of a system: its name and channel counts."""

    @property
    def name(self) -> str: ...

    @property
    def n(self) -> int: ...

    @property
    def m(self) -> int: ...


def one_line(text: object) -> str:
    return " ".join(str(text).split())


class Reporter:
    """Progress and stage lines on stderr: a tqdm bar on a terminal, plain lines in a log."""

    def __init__(self, enabled: bool, stream: TextIO | None = None):
        self.enabled = enabled
        self.stream = stream if stream is not None else sys.stderr
        try:
            self.tty = bool(self.stream.isatty())
        except (AttributeError, ValueError):
            self.tty = False
        self._bar: Any = None  # the running stage's tqdm bar (terminal only; tqdm is untyped)
        self._seen: set[tuple[type[Warning], str]] = set()
        self._last = time.monotonic()
        self.after_stage: dict[str, str] = {}  # stage -> line to announce once it is complete
        self.lost: list[str] = []  # outputs that could not be written where asked (kept in the temporary folder)

    def _close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def line(self, text: str) -> None:
        """A whole line (always ends a live progress bar first)."""
        self._close()
        print(f"{PROG}: {text}", file=self.stream, flush=True)

    def stage(self, text: str) -> None:
        if self.enabled:
            self.line(text)

    def _bar_update(self, done: int, total: int, stage: str) -> None:
        desc = f"{PROG}:   {stage}"
        if self._bar is None or self._bar.desc != desc:
            self._close()
            from tqdm import tqdm

            width = min(100, shutil.get_terminal_size((80, 24)).columns)  # a pty may report 0 columns
            self._bar = tqdm(total=total, desc=desc, file=self.stream, leave=True, ncols=width)
        self._bar.total = total
        self._bar.update(done - self._bar.n)
        if done >= total:
            self._close()

    def __call__(self, done: int, total: int, stage: str) -> None:
        """The engine's ``progress(done, total, stage)`` callback; in the main thread it also ends the run
        if a stop signal came whose interrupt a library swallowed (:func:`app.stop.check_stopped`)."""
        if threading.current_thread() is threading.main_thread():
            check_stopped()
        if not self.enabled:
            return
        if self.tty:
            self._bar_update(done, total, stage)
        else:
            # hand-written on purpose: a log wants whole lines (tqdm redraws one line with '\r'),
            # at most one a second, plus the last
            now = time.monotonic()
            if done >= total or now - self._last >= 1.0:
                print(f"{PROG}:   {stage} {done}/{total}", file=self.stream, flush=True)
                self._last = now
        if done >= total and stage in self.after_stage:
            self.line(self.after_stage.pop(stage))

    def warning(
        self,
        message: Warning | str,
        category: type[Warning],
        filename: str,
        lineno: int,
        file: TextIO | None = None,
        line: str | None = None,
    ) -> None:
        """A ``warnings.showwarning`` replacement: one line, each message once."""
        text = one_line(message)
        key = (category, text)
        if key in self._seen:
            return
        self._seen.add(key)
        self._close()
        print(f"{PROG}: warning: {text}", file=self.stream, flush=True)


def _worker_init() -> None:
    """Worker processes print warnings as one line too (:func:`app.procs.process_pool` leaves Ctrl-C to the run,
    which stops them, and ends them if the run dies)."""
    warnings.showwarning = Reporter(False).warning


def resolve_system(spec: str) -> LTISystem:
    """A preset name or a system file (``--system``); every bad file is one :class:`UsageError` line."""
    from qsid_core import get_system

    return get_system(spec)  # a bad file is a SystemDefinitionError (a ValueError: one line from main)


def system_from_args(args: argparse.Namespace) -> LTISystem:
    """The true system: ``--A``/``--B`` typed inline (a custom system), else ``--system``."""
    a_text, b_text = getattr(args, "a_text", None), getattr(args, "b_text", None)
    if a_text is None and b_text is None:
        return resolve_system(args.system)
    if a_text is None or b_text is None:
        raise UsageError("an inline system needs both --A and --B")
    from qsid_core import LTISystem
    from qsid_core.validate import parse_matrix

    A, B = parse_matrix(a_text, "A"), parse_matrix(b_text, "B")
    return LTISystem("custom", A, B, description="typed on the command line")


def quantizer_from_args(args: argparse.Namespace, system: Channels) -> QuantizerSpec:
    """The quantizer the parsed options ask for (range mode, guard, fixed limits, dither) on ``system``'s channels."""
    from qsid_core import QuantizerSpec

    fixed = args.limits
    if args.range_mode == "fixed" and fixed is None:
        raise UsageError("argument --range fixed needs --limits LO,HI (or one LO,HI per channel, ';'-separated)")
    if fixed is not None and args.range_mode != "fixed":
        raise UsageError(f"argument --limits: only used with --range fixed; got --range {args.range_mode}")
    k = system.n + system.m
    if fixed is not None and len(fixed) not in (1, k):
        raise UsageError(
            f"argument --limits: give 1 pair or {k} pairs (states then inputs) for system "
            f"{system.name!r}; got {len(fixed)}"
        )
    return QuantizerSpec(
        dither=args.dither,
        range_mode=args.range_mode,
        guard=args.guard,
        fixed_range=None if fixed is None else (fixed[0] if len(fixed) == 1 else fixed),
    )


def config(args: argparse.Namespace, system: LTISystem, mpc: bool) -> SweepConfig:
    """The engine's :class:`~qsid_core.SweepConfig` for parsed arguments (shapes checked before any work)."""
    from app.settings.cli import given_seeds
    from app.settings.schema import engine_field, plain
    from qsid_core import SweepConfig, parse_bits
    from qsid_core.validate import MAX_MAGNITUDE

    bits = parse_bits(args.bits)
    if args.rho is not None and not 0 < args.rho <= MAX_MAGNITUDE:
        raise UsageError(f"argument --rho: must be > 0 and at most {MAX_MAGNITUDE:g}; got {args.rho:g}")
    seeds: dict[str, Any] = given_seeds(args)  # typed, else --seed's; else SweepConfig's defaults
    extra: dict[str, Any] = {}
    if getattr(args, "input_bits", None) is not None:
        extra["input_bits"] = args.input_bits
    if getattr(args, "state_bits", None) is not None:
        extra["state_bits"] = args.state_bits
    if getattr(args, "noise", None) is not None:
        extra["noise"] = args.noise
    if getattr(args, "noise_known", False):
        extra["noise_known"] = True
    cfg = SweepConfig(
        system=system,
        bits=bits,
        # the options of the settings table whose value is the engine's (data size, amplitudes, theta, ...)
        **{engine_field(s): getattr(args, s.dest) for s in plain("sweep", cli=True)},
        quantizer=quantizer_from_args(args, system),
        estimator=args.estimator,
        mpc=mpc_config(args, system) if mpc else None,
        rho=args.rho,
        **seeds,
        **extra,
    )
    check_channels(cfg, system)
    return cfg


def check_channels(cfg: SweepConfig | DataLengthConfig, system: LTISystem) -> None:
    """Per-channel settings of a sweep or a data-length study against the system's shape (one line, before any
    work)."""
    from qsid_core.quantization import channel_bits

    # SweepConfig types these as object; its checks make them None, a bit count or tuples
    input_bits: Any = cfg.input_bits
    state_bits: Any = cfg.state_bits
    noise: Any = cfg.noise
    channel_bits(cfg.bits if isinstance(cfg.bits, int) else cfg.bits[0], system.n, system.m, input_bits, state_bits)
    if len(noise) not in (1, system.n):
        raise UsageError(f"argument --noise: give 1 or {system.n} values for system {system.name!r}; got {len(noise)}")


def workers(args: argparse.Namespace, rep: Reporter) -> int:
    """``--workers``, capped at the machine's CPU count (said on stderr when it is)."""
    cpus = os.cpu_count() or 1
    if args.workers > cpus:
        rep.line(f"note: --workers {args.workers} capped to {cpus} (the CPU count of this machine)")
        return cpus
    return args.workers


def _executor(workers: int, threads: int = 1) -> Executor:
    from qsid_core import InlineExecutor

    if workers > 1:
        from app.procs import process_pool  # loky: imported only for worker processes

        return process_pool(workers, _worker_init)
    if threads > 1:  # one process; the numba kernels release the GIL (results equal the inline run's, tested)
        return ThreadPoolExecutor(max_workers=threads, thread_name_prefix="qsid")
    return InlineExecutor()


@contextlib.contextmanager
def executor(args: argparse.Namespace, rep: Reporter) -> Iterator[tuple[Executor, int]]:
    """The executor of a run and its task count: ``--dask`` (a dask.distributed cluster), else ``--workers``."""
    spec = getattr(args, "dask", None)
    if spec is not None:
        if args.workers != 1:
            raise UsageError("argument --dask: use either --dask or --workers (the cluster's workers do the work)")
        from app.dask_cluster import make_executor

        with make_executor(spec, progress=rep.stage) as pool:
            nw = max(1, int(getattr(pool, "workers", 1) or 1))
            yield pool, nw
        return
    nw = workers(args, rep)
    threads = 1 if nw > 1 else min(getattr(args, "threads", 1), os.cpu_count() or 1)
    local = _executor(nw, threads)
    try:
        yield local, max(nw, threads)
    except BaseException:  # interrupted or failed: running tasks are not waited for (workers killed)
        _stop(local, kill=True)
        raise
    _stop(local)


def _stop(ex: Executor, kill: bool = False) -> None:
    """Shut ``ex`` down; ``kill``: a process pool's workers killed (busy, hung or stopped ones too: loky's
    ``kill_workers``), another executor's queued tasks cancelled, instead of waiting for them."""
    loky = sys.modules.get("loky")  # (imported only for worker processes: :func:`app.procs.process_pool`)
    if loky is not None and isinstance(ex, loky.ProcessPoolExecutor):
        ex.shutdown(kill_workers=kill)
    else:
        ex.shutdown(wait=True, cancel_futures=kill)


def _plural(k: int, word: str) -> str:
    return f"{k} {word}" + ("" if k == 1 else "s")


def bits_text(bits: Sequence[int]) -> str:
    b = list(bits)
    if len(b) > 2 and b == list(range(b[0], b[-1] + 1)):
        return f"{b[0]}..{b[-1]}"
    return ",".join(map(str, b))


def run(
    args: argparse.Namespace,
    system: LTISystem,
    mpc: bool,
    rep: Reporter,
    extra_bits: Sequence[int] = (),
    cfg: SweepConfig | None = None,
) -> tuple[SweepResult, Experiment]:
    """Run the sweep (and the closed loops at ``extra_bits``); returns (SweepResult, Experiment).

    ``cfg`` (e.g. from :func:`config_from_file`) replaces the settings built from ``args``.
    """
    from qsid_core import Experiment, Study, SweepResult

    cfg = config(args, system, mpc) if cfg is None else cfg
    with executor(args, rep) as (pool, nw):
        study = Study(cfg, pool, workers=nw, tasks=max(4, 2 * nw))
        ex = study.experiment
        assert isinstance(ex, Experiment)
        rep.stage(
            f"system {system.name!r} ({_plural(system.n, 'state')}, {_plural(system.m, 'input')}); "
            f"{cfg.trajectories} x {cfg.steps} samples, b = {bits_text(cfg.bits)}, "
            f"{cfg.realizations} realizations, "
            + (
                f"{nw} worker(s)"
                if args.workers > 1 or getattr(args, "dask", None)
                else f"in-process, {_plural(nw, 'thread')}"
            )
        )
        rep.stage("[1/2] simulate data, quantize and identify")
        rep.after_stage["quantize + identify"] = (
            f"[2/2] Theorem 1, ultimate bound and MPC closed loops ({len(cfg.bits)} word lengths "
            f"x {cfg.realizations} realizations)"
            if mpc
            else "[2/2] Theorem 1 and ultimate bound"
        )
        res = study.run(progress=rep)
        assert isinstance(res, SweepResult)
        rep.after_stage.clear()
        todo = [b for b in extra_bits if b not in res.loops]
        if todo:
            rep.stage(f"[+] closed loops for the phase portraits at b = {bits_text(todo)}")
            ex.moments(todo, rep)
            ex.closed_loops_many(todo, progress=rep)
        return res, ex
