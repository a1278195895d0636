"""The ``qsid`` command line: list systems, sweep the word length, reproduce the letter's figures.

::

    qsid systems [--json]
    qsid sweep   [--system NAME|FILE] [--bits SPEC] [...] [--json] [--out FILE]
    qsid reproduce --system dc-motor|boeing747 --out DIR [...]

All numerics are the engine's (:mod:`qsid_core`); this module parses arguments,
reports progress on stderr, formats tables and writes files. Every user error
(bad option, bad bits spec, unreadable system file, engine ``ValueError``) is
one line ``qsid: error: ...`` on stderr with exit code 2, never a traceback.
Warnings (e.g. an uncontrollable custom system) are one line ``qsid: warning: ...``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
import warnings
from concurrent.futures import Executor, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any, Sequence, TextIO

__all__ = ["main", "build_parser"]

PROG = "qsid"
PORTRAIT_BITS = (2, 4, 6)
MAX_WORKERS = 256


# ----------------------------------------------------------------------------------------
# argument parsing
# ----------------------------------------------------------------------------------------
class UsageError(Exception):
    """A bad command line (reported as one line, exit code 2)."""


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one line (raised, so ``main(argv)`` can return 2)."""

    def error(self, message: str):  # type: ignore[override]
        raise UsageError(message)


def _int_type(name: str, lo: int):
    def conv(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be an integer; got {text!r}") from None
        if v < lo:
            kind = "positive" if lo == 1 else f">= {lo}"
            raise argparse.ArgumentTypeError(f"must be {kind}; got {v}")
        return v

    conv.__name__ = name
    return conv


def _float_type(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number; got {text!r}") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"must be finite; got {text!r}")
    return v


def _floats_type(text: str) -> tuple[float, ...]:
    """``1`` or ``1,0.5`` (one value for every input, or one per input)."""
    parts = [p for p in text.split(",") if p.strip()]
    if not parts:
        raise argparse.ArgumentTypeError(f"must be a number or a comma-separated list of numbers; got {text!r}")
    out = []
    for p in parts:
        try:
            v = float(p)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be a number or comma-separated numbers; got {text!r}") from None
        if not math.isfinite(v) or v <= 0:
            raise argparse.ArgumentTypeError(f"must be positive and finite; got {text!r}")
        out.append(v)
    return tuple(out)


_pos_int = _int_type("positive integer", 1)
_nonneg_int = _int_type("non-negative integer", 0)


def _add_run_options(p: argparse.ArgumentParser, bits_default: str) -> None:
    """Options shared by ``sweep`` and ``reproduce`` (defaults are the engine's)."""
    g = p.add_argument_group("system and data")
    g.add_argument("--system", default="dc-motor", metavar="NAME|FILE",
                   help="preset name (see 'qsid systems') or a .toml/.json file with A, B [, x0, Q, R, dt] "
                        "(default: dc-motor)")
    g.add_argument("--bits", default=bits_default, metavar="SPEC",
                   help=f"word lengths: '2:12' (inclusive), '2:12:2' (step), '2,4,6' or '8' "
                        f"(default: {bits_default})")
    g.add_argument("--realizations", type=_pos_int, default=50, metavar="N",
                   help="dither realizations per word length (default: 50)")
    g.add_argument("--trajectories", type=_pos_int, default=200, metavar="N",
                   help="simulated trajectories (default: 200)")
    g.add_argument("--steps", type=_pos_int, default=1000, metavar="N",
                   help="samples per trajectory (default: 1000)")
    g.add_argument("--seed", type=_nonneg_int, default=None, metavar="N",
                   help="seed of both the data and the dither streams (default: data 0, dither 1)")
    q = p.add_argument_group("quantizer and identification")
    q.add_argument("--range", dest="range_mode", choices=("per-channel", "shared"), default="per-channel",
                   help="quantizer range: min/max per channel, or one range for all (default: per-channel)")
    q.add_argument("--guard", action="store_true",
                   help="widen the range by half a cell on each side (no overload)")
    q.add_argument("--dither", choices=("subtractive", "none"), default="subtractive",
                   help="subtractive uniform dither or none (default: subtractive)")
    q.add_argument("--estimator", choices=("ls", "bcls"), default="ls",
                   help="least squares or bias-compensated LS (default: ls)")
    m = p.add_argument_group("MPC and ultimate bound")
    m.add_argument("--horizon", type=_pos_int, default=10, metavar="N", help="MPC horizon (default: 10)")
    m.add_argument("--mpc-steps", type=_pos_int, default=50, metavar="N",
                   help="closed-loop steps on the true system (default: 50)")
    m.add_argument("--u-max", type=_floats_type, default=(1.0,), metavar="X",
                   help="input bound |u_i| <= X; one value or one per input, comma-separated (default: 1)")
    m.add_argument("--theta", type=_float_type, default=0.5, metavar="X",
                   help="theta of the ultimate bound, in (0, 1) (default: 0.5)")
    m.add_argument("--rho", type=_float_type, default=None, metavar="X",
                   help="rho of the ultimate bound, > 0 (default: the level-set ball through x0)")
    r = p.add_argument_group("running")
    r.add_argument("--workers", type=_pos_int, default=1, metavar="N",
                   help="processes (N > 1 uses a ProcessPoolExecutor; default: 1, in-process)")
    r.add_argument("-q", "--quiet", action="store_true", help="no progress on stderr")


def build_parser() -> argparse.ArgumentParser:
    """The ``qsid`` argument parser (errors raise :class:`UsageError`)."""
    parser = _Parser(
        prog=PROG,
        description="Quantized system identification and the MPC built on it (the QSID-MPC letter).",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    ps = sub.add_parser("systems", help="list the preset systems",
                        description="List the preset systems (name, states n, inputs m, description).")
    ps.add_argument("--json", action="store_true", help="print JSON instead of a table")

    pw = sub.add_parser("sweep", help="sweep the word length b: identification errors, theory, MPC cost",
                        description="Sweep the word length b: identification errors (mean +- std over dither "
                                    "realizations), Theorem 1 prediction, overload, MPC cost on the true "
                                    "system, ultimate bound.")
    _add_run_options(pw, "1:16")
    pw.add_argument("--no-mpc", action="store_true", help="skip the MPC closed loops (identification and theory)")
    pw.add_argument("--json", action="store_true", help="print one JSON object to stdout instead of a table")
    pw.add_argument("--out", metavar="FILE", default=None, help="also write the JSON to FILE")

    pr = sub.add_parser("reproduce", help="write the letter's figure panels (a)-(f) as offline HTML",
                        description="Write the letter's figure panels as standalone offline HTML: (a)/(b) "
                                    "relative errors of A and B vs b, (c) MPC cost vs b, (d)-(f) closed-loop "
                                    "phase portraits for b = 2, 4, 6; plus index.html and data.json.")
    _add_run_options(pr, "1:16")
    pr.add_argument("--out", metavar="DIR", required=True, help="output directory (created if missing)")
    return parser


# ----------------------------------------------------------------------------------------
# stderr reporting: progress, stages, warnings, errors
# ----------------------------------------------------------------------------------------
def _one_line(text: object) -> str:
    return " ".join(str(text).split())


class Reporter:
    """Progress and stage lines on stderr (a live ``\\r`` line on a terminal)."""

    def __init__(self, enabled: bool, stream: TextIO | None = None):
        self.enabled = enabled
        self.stream = stream if stream is not None else sys.stderr
        try:
            self.tty = bool(self.stream.isatty())
        except (AttributeError, ValueError):
            self.tty = False
        self._open = False
        self._seen: set = set()
        self._last = time.monotonic()
        self.after_stage: dict[str, str] = {}  # stage -> line to announce once it is complete

    def _close(self) -> None:
        if self._open:
            self.stream.write("\n")
            self._open = False

    def line(self, text: str) -> None:
        """A whole line (always ends a live progress line first)."""
        self._close()
        print(f"{PROG}: {text}", file=self.stream, flush=True)

    def stage(self, text: str) -> None:
        if self.enabled:
            self.line(text)

    def __call__(self, done: int, total: int, stage: str) -> None:
        """The engine's ``progress(done, total, stage)`` callback."""
        if not self.enabled:
            return
        if self.tty:
            width = 24
            fill = int(width * done / max(total, 1))
            self.stream.write(f"\r{PROG}:   {stage} [{'#' * fill}{'.' * (width - fill)}] {done}/{total}")
            self.stream.flush()
            self._open = True
            if done >= total:
                self._close()
        else:  # a log: at most one line a second, plus the last
            now = time.monotonic()
            if done >= total or now - self._last >= 1.0:
                print(f"{PROG}:   {stage} {done}/{total}", file=self.stream, flush=True)
                self._last = now
        if done >= total and stage in self.after_stage:
            self.line(self.after_stage.pop(stage))

    def warning(self, message, category, filename, lineno, file=None, line=None) -> None:
        """A ``warnings.showwarning`` replacement: one line, each message once."""
        text = _one_line(message)
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


# ----------------------------------------------------------------------------------------
# executors
# ----------------------------------------------------------------------------------------
# ----------------------------------------------------------------------------------------
# configuration
# ----------------------------------------------------------------------------------------
def _resolve_system(spec: str):
    from qsid_core.systems import get_system

    p = Path(spec)
    if spec.lower().endswith((".toml", ".json")) and p.exists() and not p.is_file():
        raise UsageError(f"system file {spec!r} is not a regular file")
    return get_system(spec)


def _config(args, system, mpc: bool):
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


def _run(args, system, mpc: bool, rep: Reporter, extra_bits: Sequence[int] = ()):
    """Run the sweep (and closed loops at ``extra_bits``); returns (result, experiment, executor)."""
    from qsid_core import Experiment, run_sweep

    cfg = _config(args, system, mpc)
    ex_pool = _executor(args.workers)
    try:
        ex = Experiment(cfg, ex_pool, tasks=max(4, 2 * args.workers))
        n_stages = 2
        rep.stage(f"system {system.name!r} ({_plural(system.n, 'state')}, {_plural(system.m, 'input')}); "
                  f"{cfg.trajectories} x {cfg.steps} samples, b = {_bits_text(cfg.bits)}, "
                  f"{cfg.realizations} realizations, {args.workers} worker(s)")
        rep.stage(f"[1/{n_stages}] simulate data, quantize and identify")
        rep.after_stage["quantize + identify"] = (
            f"[2/{n_stages}] Theorem 1, ultimate bound and MPC closed loops ({len(cfg.bits)} word lengths "
            f"x {cfg.realizations} realizations)" if mpc else f"[2/{n_stages}] Theorem 1 and ultimate bound")
        res = run_sweep(cfg, ex_pool, progress=rep, experiment=ex)
        rep.after_stage.clear()
        todo = [b for b in extra_bits if b not in res.loops]
        if todo:
            rep.stage(f"[+] closed loops for the phase portraits at b = {_bits_text(todo)}")
            ex.moments(todo, rep)
            ex.closed_loops_many(todo, progress=rep)
        return res, ex
    finally:
        ex_pool.shutdown(wait=True, cancel_futures=True)


# ----------------------------------------------------------------------------------------
# output helpers
# ----------------------------------------------------------------------------------------
def _clean(obj: Any) -> Any:
    """JSON-ready copy: non-finite floats become None, numpy scalars/arrays plain Python."""
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if hasattr(obj, "tolist") and not isinstance(obj, (str, bytes)):
        return _clean(obj.tolist())
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    return obj


def _dumps(obj: Any, indent: int | None = 2) -> str:
    return json.dumps(_clean(obj), indent=indent, allow_nan=False)


def _g(v, fmt: str = ".3g", none: str = "-") -> str:
    return none if v is None else format(v, fmt)


def _pm(stats: dict | None) -> str:
    if not stats or stats.get("mean") is None:
        return "-"
    return f"{stats['mean']:.3e} +/- {stats['std']:.1e}"


def format_table(d: dict) -> str:
    """The readable table of a sweep dict (``SweepResult.to_dict()``)."""
    head = ["b", "eps min..max", "err_A mean +/- std", "Thm1 A", "err_B mean +/- std", "Thm1 B", "overload",
            "MPC cost (failed)", "delta bound", "|x_T| mean"]
    rows = []
    for r in d["results"]:
        eps = list(r["eps_x"]) + list(r["eps_u"])
        cost = r.get("mpc_cost")
        cost_s = "-" if cost is None else f"{_g(cost.get('mean'), '.4g')} ({cost.get('failed', 0)})"
        fsn = r.get("final_state_norm")
        rows.append([
            str(r["bits"]),
            f"{min(eps):.2e}..{max(eps):.2e}",
            _pm(r["err_A"]),
            _g(r["err_A_theory"], ".3e"),
            _pm(r["err_B"]),
            _g(r["err_B_theory"], ".3e"),
            f"{100 * r['overload_fraction']:.2f}%",
            cost_s,
            _g(r["ultimate_bound"], ".3e"),
            "-" if fsn is None else _g(fsn.get("mean"), ".2e"),
        ])
    widths = [max(len(h), *(len(row[i]) for row in rows)) if rows else len(h) for i, h in enumerate(head)]
    left = {1}

    def fmt(cells):
        return "  ".join(c.ljust(w) if i in left else c.rjust(w) for i, (c, w) in enumerate(zip(cells, widths)))

    c = d["config"]
    lines = [
        f"system {d['system']}: {c['trajectories']} x {c['steps']} samples, {c['realizations']} realizations, "
        f"range {c['range']}{' + guard' if c['guard'] else ''}, dither {c['dither']}, estimator {c['estimator']}"
        + ("" if c["mpc"] is None else
           f", MPC horizon {c['mpc']['horizon']}, {c['mpc']['steps']} steps, u_max "
           f"{','.join(format(u, 'g') for u in c['mpc']['u_max'])}"),
        fmt(head),
        fmt(["-" * w for w in widths]),
        *(fmt(row) for row in rows),
    ]
    t = d.get("timing_s", {})
    slope = (f"slope of log10 mean error per bit: A {_g(d.get('slope_A'), '+.3f')}, "
             f"B {_g(d.get('slope_B'), '+.3f')} (letter: -0.301 = -log10 2)")
    true_cost = ("MPC off" if c["mpc"] is None else
                 f"true-model MPC cost {_g(d.get('mpc_cost_true_model'), '.4g')}")
    timing = "time " + ", ".join(f"{k} {v:.2f} s" for k, v in t.items())
    lines.append(f"{slope}; {true_cost}; {timing}")
    fails: dict = {}
    for r in d["results"]:
        for kind, k in ((r.get("mpc_cost") or {}).get("failures") or {}).items():
            fails[kind] = fails.get(kind, 0) + k
    if fails:
        lines.append("MPC failures by kind: " + ", ".join(f"{k} {v}" for k, v in sorted(fails.items())))
    fb = sum(r.get("bcls_fallbacks", 0) for r in d["results"])
    if fb:
        lines.append(f"BCLS fell back to LS in {fb} realization(s) (corrected Gram matrix not positive definite)")
    return "\n".join(lines)


def _check_writable(directory: Path) -> None:
    if not os.access(directory, os.W_OK):
        raise UsageError(f"argument --out: cannot write into {str(directory)!r} (permission denied)")


def _write_text(path: Path, text: str) -> None:
    path.write_text(text, encoding="utf-8")


# ----------------------------------------------------------------------------------------
# commands
# ----------------------------------------------------------------------------------------
def cmd_systems(args, rep: Reporter) -> int:
    from qsid_core.systems import PRESETS

    items = []
    for name, make in PRESETS.items():
        s = make()
        items.append({"name": name, "n": s.n, "m": s.m, "dt": s.dt, "description": s.description,
                      "states": list(s.state_names), "inputs": list(s.input_names)})
    if args.json:
        print(_dumps(items))
        return 0
    w = max(len("name"), *(len(i["name"]) for i in items))
    print(f"{'name'.ljust(w)}  n  m  description")
    for i in items:
        print(f"{i['name'].ljust(w)}  {i['n']}  {i['m']}  {i['description']}")
    print("custom systems: --system FILE.toml|FILE.json with A, B and optional x0, Q, R, dt")
    return 0


def cmd_sweep(args, rep: Reporter) -> int:
    system = _resolve_system(args.system)
    out = Path(args.out) if args.out else None
    if out is not None and out.is_dir():
        raise UsageError(f"argument --out: {args.out!r} is a directory; give a file name")
    if out is not None:  # fail before the run, not after it
        out.parent.mkdir(parents=True, exist_ok=True)
        _check_writable(out.parent)
    res, _ = _run(args, system, not args.no_mpc, rep)
    d = res.to_dict()
    text = _dumps(d)
    if out is not None:
        _write_text(out, text + "\n")
    rep.stage(f"done in {d['timing_s']['total']:.2f} s" + (f"; JSON written to {out}" if out else ""))
    if args.json:
        print(text)
    else:
        print(format_table(d))
    return 0


def cmd_reproduce(args, rep: Reporter) -> int:
    """``qsid reproduce``: the letter's figure panels (see :mod:`app.reproduce`)."""
    from app.reproduce import reproduce

    return reproduce(args, rep)


COMMANDS = {"systems": cmd_systems, "sweep": cmd_sweep, "reproduce": cmd_reproduce}


# ----------------------------------------------------------------------------------------
# entry point
# ----------------------------------------------------------------------------------------
def main(argv: Sequence[str] | None = None) -> int:
    """Run ``qsid`` with ``argv`` (default ``sys.argv[1:]``); returns the exit code.

    0 success, 2 bad input or engine error (one line on stderr), 130 interrupted.
    """
    rep = Reporter(True)

    def fail(message: object, code: int = 2) -> int:
        rep.line(f"error: {_one_line(message)}")
        return code

    with warnings.catch_warnings():
        warnings.simplefilter("default")
        warnings.showwarning = rep.warning
        try:
            args = build_parser().parse_args(list(sys.argv[1:] if argv is None else argv))
            if args.command is None:
                raise UsageError(f"give a command: {', '.join(COMMANDS)} (see '{PROG} --help')")
            rep.enabled = not getattr(args, "quiet", False)
            return COMMANDS[args.command](args, rep)
        except UsageError as exc:
            return fail(exc)
        except ValueError as exc:  # every qsid_core user error is a ValueError subclass
            return fail(exc)
        except MemoryError:
            return fail("not enough memory for this run; reduce --trajectories, --steps, --realizations or --bits")
        except BrokenProcessPool:
            return fail("a worker process died (out of memory?); try fewer --workers", 1)
        except OSError as exc:
            where = f" {exc.filename!r}" if getattr(exc, "filename", None) else ""
            return fail(f"cannot read or write{where}: {exc.strerror or exc}")
        except KeyboardInterrupt:
            rep.line("interrupted")
            return 130


if __name__ == "__main__":
    raise SystemExit(main())
