"""What every ``qsid`` command that computes shares: progress on stderr, the engine config from the
arguments, the executor, and :func:`run` (the sweep plus optional extra closed loops).

Commands import this module (and :mod:`app.cli.output`), never each other.
"""

from __future__ import annotations

import os
import shutil
import sys
import time
import warnings
from concurrent.futures import Executor, ProcessPoolExecutor
from pathlib import Path
from typing import Sequence, TextIO

from tqdm import tqdm

from .parser import PROG, UsageError

__all__ = ["UsageError", "Reporter", "one_line", "resolve_system", "config", "run", "check_writable",
           "write_text", "MAX_WORKERS"]

MAX_WORKERS = 256


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
        self._bar: tqdm | None = None  # the running stage's bar (terminal only)
        self._seen: set = set()
        self._last = time.monotonic()
        self.after_stage: dict[str, str] = {}  # stage -> line to announce once it is complete

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
            width = min(100, shutil.get_terminal_size((80, 24)).columns)  # a pty may report 0 columns
            self._bar = tqdm(total=total, desc=desc, file=self.stream, leave=True, ncols=width)
        self._bar.total = total
        self._bar.update(done - self._bar.n)
        if done >= total:
            self._close()

    def __call__(self, done: int, total: int, stage: str) -> None:
        """The engine's ``progress(done, total, stage)`` callback."""
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

    def warning(self, message, category, filename, lineno, file=None, line=None) -> None:
        """A ``warnings.showwarning`` replacement: one line, each message once."""
        text = one_line(message)
        key = (category, text)
        if key in self._seen:
            return
        self._seen.add(key)
        self._close()
        print(f"{PROG}: warning: {text}", file=self.stream, flush=True)


def _worker_init() -> None:
    """Worker processes print warnings as one line too."""
    rep = Reporter(False)
    warnings.showwarning = rep.warning


def resolve_system(spec: str):
    """A preset name or a system file (``--system``)."""
    from qsid_core.systems import get_system

    p = Path(spec)
    if spec.lower().endswith((".toml", ".json")) and p.exists() and not p.is_file():
        raise UsageError(f"system file {spec!r} is not a regular file")
    return get_system(spec)


def config(args, system, mpc: bool):
    """The engine's :class:`~qsid_core.SweepConfig` for parsed arguments (shapes checked before any work)."""
    from qsid_core import MPCConfig, QuantizerSpec, SweepConfig, parse_bits

    bits = parse_bits(args.bits)
    if args.u_max is not None and len(args.u_max) not in (1, system.m):
        raise UsageError(f"argument --u-max: give 1 or {system.m} values for system {system.name!r}; "
                         f"got {len(args.u_max)}")
    if args.rho is not None and args.rho <= 0:
        raise UsageError(f"argument --rho: must be > 0; got {args.rho:g}")
    if args.workers > MAX_WORKERS:
        raise UsageError(f"argument --workers: must be at most {MAX_WORKERS}; got {args.workers}")
    seeds = {} if args.seed is None else {"data_seed": args.seed, "dither_seed": args.seed}
    u_max = args.u_max[0] if len(args.u_max) == 1 else args.u_max
    mcfg = MPCConfig(horizon=args.horizon, steps=args.mpc_steps, u_max=u_max) if mpc else None
    if mcfg is not None:
        mcfg.resolve(system)  # shape checks now, before any work
    return SweepConfig(
        system=system, bits=bits, realizations=args.realizations, trajectories=args.trajectories,
        steps=args.steps, quantizer=QuantizerSpec(dither=args.dither, range_mode=args.range_mode, guard=args.guard),
        estimator=args.estimator, mpc=mcfg, theta=args.theta, rho=args.rho, **seeds,
    )


def _executor(workers: int) -> Executor:
    from qsid_core import InlineExecutor

    if workers > 1:
        return ProcessPoolExecutor(max_workers=workers, initializer=_worker_init)
    return InlineExecutor()


def _plural(k: int, word: str) -> str:
    return f"{k} {word}" + ("" if k == 1 else "s")


def _bits_text(bits: Sequence[int]) -> str:
    bits = list(bits)
    if len(bits) > 2 and bits == list(range(bits[0], bits[-1] + 1)):
        return f"{bits[0]}..{bits[-1]}"
    return ",".join(map(str, bits))


def run(args, system, mpc: bool, rep: Reporter, extra_bits: Sequence[int] = ()):
    """Run the sweep (and the closed loops at ``extra_bits``); returns (SweepResult, Experiment)."""
    from qsid_core import Experiment, run_sweep

    cfg = config(args, system, mpc)
    pool = _executor(args.workers)
    try:
        ex = Experiment(cfg, pool, tasks=max(4, 2 * args.workers))
        rep.stage(f"system {system.name!r} ({_plural(system.n, 'state')}, {_plural(system.m, 'input')}); "
                  f"{cfg.trajectories} x {cfg.steps} samples, b = {_bits_text(cfg.bits)}, "
                  f"{cfg.realizations} realizations, {args.workers} worker(s)")
        rep.stage("[1/2] simulate data, quantize and identify")
        rep.after_stage["quantize + identify"] = (
            f"[2/2] Theorem 1, ultimate bound and MPC closed loops ({len(cfg.bits)} word lengths "
            f"x {cfg.realizations} realizations)" if mpc else "[2/2] Theorem 1 and ultimate bound")
        res = run_sweep(cfg, pool, progress=rep, experiment=ex)
        rep.after_stage.clear()
        todo = [b for b in extra_bits if b not in res.loops]
        if todo:
            rep.stage(f"[+] closed loops for the phase portraits at b = {_bits_text(todo)}")
            ex.moments(todo, rep)
            ex.closed_loops_many(todo, progress=rep)
        return res, ex
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def check_writable(directory: Path) -> None:
    if not os.access(directory, os.W_OK):
        raise UsageError(f"argument --out: cannot write into {str(directory)!r} (permission denied)")


def write_text(path: Path, text: str) -> None:
    path.write_text(text, encoding="utf-8")
