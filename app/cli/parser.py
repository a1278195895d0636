"""The ``qsid`` argument parser: value types, the options every run shares, one-line errors.

Defaults and choices are the engine's (``SweepConfig()``, ``MPCConfig()``,
``QuantizerSpec()``, ``DITHERS``, ``RANGE_MODES``, ``ESTIMATORS``); nothing is typed twice.
Each command adds its own options (``add_arguments`` in its module).
"""

from __future__ import annotations

import argparse
import math
from types import ModuleType
from typing import Mapping

from qsid_core.experiment import SweepConfig
from qsid_core.identify import ESTIMATORS
from qsid_core.mpc import MPCConfig
from qsid_core.quantize import DITHERS, RANGE_MODES, QuantizerSpec

__all__ = ["PROG", "UsageError", "build_parser", "add_run_options", "bits_spec", "pos_int"]

PROG = "qsid"
_SWEEP = SweepConfig(mpc=None)  # the engine's defaults
_MPC = MPCConfig()
_QUANT = QuantizerSpec()
#: Range modes the command line offers ("fixed" needs typed ranges, which only the dashboard has).
CLI_RANGE_MODES = tuple(m for m in RANGE_MODES if m != "fixed")


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


pos_int = _int_type("positive integer", 1)
_nonneg_int = _int_type("non-negative integer", 0)


def bits_spec(bits) -> str:
    """Word lengths as the ``--bits`` text (``(1, ..., 16)`` -> ``"1:16"``)."""
    bits = list(bits)
    if len(bits) > 1 and bits == list(range(bits[0], bits[-1] + 1)):
        return f"{bits[0]}:{bits[-1]}"
    return ",".join(map(str, bits))


def _g(v) -> str:
    return format(v, "g")


def _add_data_options(p: argparse.ArgumentParser) -> None:
    bits_default = bits_spec(_SWEEP.bits)
    g = p.add_argument_group("system and data")
    g.add_argument("--system", default=_SWEEP.system, metavar="NAME|FILE",
                   help="preset name (see 'qsid systems') or a .toml/.json file with A, B [, x0, Q, R, dt] "
                        f"(default: {_SWEEP.system})")
    g.add_argument("--bits", default=bits_default, metavar="SPEC",
                   help=f"word lengths: '2:12' (inclusive), '2:12:2' (step), '2,4,6' or '8' "
                        f"(default: {bits_default})")
    g.add_argument("--realizations", type=pos_int, default=_SWEEP.realizations, metavar="N",
                   help=f"dither realizations per word length (default: {_SWEEP.realizations})")
    g.add_argument("--trajectories", type=pos_int, default=_SWEEP.trajectories, metavar="N",
                   help=f"simulated trajectories (default: {_SWEEP.trajectories})")
    g.add_argument("--steps", type=pos_int, default=_SWEEP.steps, metavar="N",
                   help=f"samples per trajectory (default: {_SWEEP.steps})")
    g.add_argument("--seed", type=_nonneg_int, default=None, metavar="N",
                   help=f"seed of both the data and the dither streams (default: data {_SWEEP.data_seed}, "
                        f"dither {_SWEEP.dither_seed})")
    q = p.add_argument_group("quantizer and identification")
    q.add_argument("--range", dest="range_mode", choices=CLI_RANGE_MODES, default=_QUANT.range_mode,
                   help=f"quantizer range: min/max per channel, or one range for all (default: {_QUANT.range_mode})")
    q.add_argument("--guard", action="store_true",
                   help="widen the range by half a cell on each side (no overload)")
    q.add_argument("--dither", choices=DITHERS, default=_QUANT.dither,
                   help=f"subtractive uniform dither or none (default: {_QUANT.dither})")
    q.add_argument("--estimator", choices=ESTIMATORS, default=_SWEEP.estimator,
                   help=f"least squares or bias-compensated LS (default: {_SWEEP.estimator})")


def add_run_options(p: argparse.ArgumentParser) -> None:
    """Options shared by ``sweep`` and ``reproduce`` (defaults are the engine's)."""
    _add_data_options(p)
    m = p.add_argument_group("MPC and ultimate bound")
    m.add_argument("--horizon", type=pos_int, default=_MPC.horizon, metavar="N",
                   help=f"MPC horizon (default: {_MPC.horizon})")
    m.add_argument("--mpc-steps", type=pos_int, default=_MPC.steps, metavar="N",
                   help=f"closed-loop steps on the true system (default: {_MPC.steps})")
    m.add_argument("--u-max", type=_floats_type, default=_MPC.u_max, metavar="X",
                   help="input bound |u_i| <= X; one value or one per input, comma-separated "
                        f"(default: {','.join(map(_g, _MPC.u_max))})")
    m.add_argument("--theta", type=_float_type, default=_SWEEP.theta, metavar="X",
                   help=f"theta of the ultimate bound, in (0, 1) (default: {_g(_SWEEP.theta)})")
    m.add_argument("--rho", type=_float_type, default=None, metavar="X",
                   help="rho of the ultimate bound, > 0 (default: the level-set ball through x0)")
    r = p.add_argument_group("running")
    r.add_argument("--workers", type=pos_int, default=1, metavar="N",
                   help="processes (N > 1 uses a ProcessPoolExecutor; default: 1, in-process)")
    r.add_argument("-q", "--quiet", action="store_true", help="no progress on stderr")


def build_parser(commands: Mapping[str, ModuleType]) -> argparse.ArgumentParser:
    """The ``qsid`` parser with one subcommand per module in ``commands`` (errors raise :class:`UsageError`).

    Each module has ``HELP``, ``DESCRIPTION`` and ``add_arguments(parser)``.
    """
    parser = _Parser(
        prog=PROG,
        description="Quantized system identification and the MPC built on it (the QSID-MPC letter).",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name, mod in commands.items():
        mod.add_arguments(sub.add_parser(name, help=mod.HELP, description=mod.DESCRIPTION))
    return parser
