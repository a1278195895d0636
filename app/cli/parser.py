"""The ``qsid`` argument parser: value types, the options every run shares, one-line errors.

Defaults and choices are the engine's (``SweepConfig()``, ``MPCConfig()``,
``QuantizerSpec()``, ``DITHERS``, ``RANGE_MODES``, ``ESTIMATORS``); nothing is typed twice.
Each command adds its own options (``add_arguments`` in its module).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Mapping
from types import ModuleType
from typing import TYPE_CHECKING, Any, NoReturn

from app.settings.cli import add_seed_option, add_setting_options, float_type, int_type, shown
from app.settings.command import bits_spec, floats_spec, limits_spec
from app.settings.schema import DATA_GROUP, LOOP_GROUP, MPC_GROUP, WHATIF_GROUP, engine

if TYPE_CHECKING:
    from qsid_core import SweepConfig

__all__ = [
    "PROG",
    "any_float",
    "nonneg_int",
    "add_quantizer_options",
    "UsageError",
    "engine",
    "build_parser",
    "add_run_options",
    "add_data_options",
    "bits_spec",
    "pos_int",
    "limits_spec",
    "floats_spec",
]

PROG = "qsid"
_DATA, _WHATIF, _MPC, _LOOP = DATA_GROUP, WHATIF_GROUP, MPC_GROUP, LOOP_GROUP


class UsageError(Exception):
    """A bad command line (reported as one line, exit code 2)."""


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one line (raised, so ``main(argv)`` can return 2)."""

    def error(self, message: str) -> NoReturn:
        if message.endswith("expected one argument"):
            message += " (a value that starts with '-' needs '=', e.g. --limits=-20,20 or --x0=-1,0,0)"
        raise UsageError(message)


any_float = float_type()


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


def _number(text: str, what: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{what}; {text.strip()!r} is not a number") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"{what}; {text.strip()!r} is not finite")
    return v


def _float_list(text: str) -> tuple[float, ...]:
    """``1,0,-0.5``: finite numbers, comma-separated (signs and sizes are the engine's to check)."""
    what = "must be a number or comma-separated numbers"
    parts = text.split(",")
    if not text.strip() or any(not p.strip() for p in parts):
        raise argparse.ArgumentTypeError(f"{what}; got {text!r}")
    return tuple(_number(p, what) for p in parts)


def _nonneg_float(text: str) -> float:
    v = _number(text, "must be a number >= 0")
    if v < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0; got {text!r}")
    return v


def _disturbance_spec(text: str) -> tuple[float, str]:
    """``SIGMA`` or ``SIGMA:gaussian`` / ``SIGMA:uniform``."""
    sigma, _, kind = text.partition(":")
    kind = kind.strip().lower() or "gaussian"
    if kind not in ("gaussian", "uniform"):
        raise argparse.ArgumentTypeError(f"must be SIGMA, SIGMA:gaussian or SIGMA:uniform; got {text!r}")
    return _nonneg_float(sigma), kind


def _feedback_bits(text: str) -> int | None:
    if text.strip().lower() in ("none", "exact"):
        return None
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a word length 1..32 or 'none'; got {text!r}") from None
    if not 1 <= v <= 32:
        raise argparse.ArgumentTypeError(f"must be a word length 1..32 or 'none'; got {text!r}")
    return v


def _qf_spec(text: str) -> str | tuple[float, ...] | None:
    """``dare`` (None: each model's DARE solution), ``Q`` (the stage weight) or a diagonal ``F1,F2,..``."""
    t = text.strip()
    if t.lower() == "dare":
        return None
    if t == "Q":
        return "Q"
    try:
        return _float_list(t)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(
            f"must be 'dare', 'Q' or numbers (one or one per state); got {text!r}"
        ) from None


def _limits(text: str) -> tuple[tuple[float, float], ...]:
    """``LO,HI`` (every channel) or ``LO,HI;LO,HI;...`` (one pair per channel: states, then inputs)."""
    what = "must be 'LO,HI' or 'LO,HI;LO,HI;...' (one pair per channel, states then inputs)"
    pairs: list[tuple[float, float]] = []
    for part in text.split(";"):
        nums = part.split(",")
        if len(nums) != 2:
            raise argparse.ArgumentTypeError(f"{what}; got {text!r}")
        lo, hi = (_number(v, what) for v in nums)
        if not lo < hi:
            raise argparse.ArgumentTypeError(f"every range needs LO < HI; got {part.strip()!r}")
        pairs.append((lo, hi))
    return tuple(pairs)


def _matrix_text(text: str) -> str:
    if not text.strip():
        raise argparse.ArgumentTypeError("must be a matrix: rows separated by ';', entries by spaces or commas")
    return text


pos_int = int_type("positive integer", 1)
nonneg_int = int_type("non-negative integer", 0)


def add_data_options(p: argparse.ArgumentParser, base: SweepConfig | None = None, seed: bool = True) -> None:
    """System, data and quantizer options; defaults from ``base`` (a SweepConfig; default the engine's).

    The options of single settings come from the settings table (:mod:`app.settings.cli`); the ones
    written here take values that are not one setting's (a system, a sweep of word lengths, one seed for two).
    """
    e = engine()
    base = e.sweep if base is None else base
    bits_default = bits_spec(base.bits)
    g = p.add_argument_group(_DATA)
    g.add_argument(
        "--system",
        default=base.system,
        metavar="NAME|FILE",
        help="preset name (see 'qsid systems') or a .toml/.json file with A, B [, x0, Q, R, dt] "
        f"(default: {base.system})",
    )
    g.add_argument(
        "--A",
        dest="a_text",
        type=_matrix_text,
        default=None,
        metavar="ROWS",
        help="a custom system typed inline, as in the dashboard: '0.9 0.1; 0 0.8' (with --B; "
        "x0 = e1, Q = I, R = I unless given)",
    )
    g.add_argument(
        "--B",
        dest="b_text",
        type=_matrix_text,
        default=None,
        metavar="ROWS",
        help="input matrix of the inline custom system, one row per state: '0; 1'",
    )
    g.add_argument(
        "--bits",
        default=bits_default,
        metavar="SPEC",
        help=f"word lengths: '2:12' (inclusive), '2:12:2' (step), '2,4,6' or '8' (default: {bits_default})",
    )
    add_setting_options(g, _DATA, base)
    if seed:
        add_seed_option(g)
    q = p.add_argument_group("quantizer and identification")
    add_quantizer_options(
        q, base.quantizer, "quantizer range: min/max per channel, one range for all, or fixed (--limits)"
    )
    add_setting_options(q, "identification", base)


def add_run_options(p: argparse.ArgumentParser, base: SweepConfig | None = None) -> None:
    """Options shared by ``sweep`` and ``reproduce`` (defaults from ``base``: the engine's or the letter's)."""
    e = engine()
    base = e.sweep if base is None else base
    add_data_options(p, base)
    add_setting_options(p.add_argument_group(_WHATIF), _WHATIF, base)
    m = p.add_argument_group(_MPC)
    add_setting_options(m, _MPC, base)
    _add_mpc_problem_options(m, e.mpc)
    _add_mpc_weight_options(m)
    _add_loop_options(p.add_argument_group(_LOOP), base)
    add_running_options(p)


def _add_mpc_problem_options(m: argparse._ArgumentGroup, mpc: Any) -> None:
    """The MPC problem's bounds, start, reference and terminal ingredients in group ``m`` (defaults from the
    engine's ``MPCConfig`` ``mpc``)."""
    m.add_argument(
        "--u-max",
        type=_floats_type,
        default=mpc.u_max,
        metavar="X",
        help="input bound |u_i| <= X; one value or one per input, comma-separated "
        f"(default: {','.join(map(shown, mpc.u_max))})",
    )
    m.add_argument(
        "--x0",
        type=_float_list,
        default=None,
        metavar="X1,X2,..",
        help="initial state of the closed loops, one per state (default: the system's x0)",
    )
    m.add_argument(
        "--x-ref",
        type=_float_list,
        default=None,
        metavar="R1,R2,..",
        help="constant reference the MPC tracks, one value or one per state (default: 0)",
    )
    m.add_argument(
        "--x-max",
        type=_float_list,
        default=None,
        metavar="X",
        help="state box |x_i| <= X on the predicted states, one value or one per state (default: none)",
    )
    m.add_argument(
        "--Qf",
        dest="qf",
        type=_qf_spec,
        default=None,
        metavar="dare|Q|F1,F2,..",
        help="terminal weight of the MPC: 'dare' (the stabilizing DARE solution of each identified "
        "model, the default), 'Q' (the stage weight) or a diagonal, one value or one per state",
    )
    m.add_argument(
        "--terminal-box",
        dest="xf_max",
        type=_float_list,
        default=None,
        metavar="X",
        help="terminal box |x_N,i| <= X_i on the last predicted state, one value or one per state (default: none)",
    )


def _add_mpc_weight_options(m: argparse._ArgumentGroup) -> None:
    """The MPC's state and input weights and the rho of the ultimate bound in group ``m``."""
    m.add_argument(
        "--Q",
        dest="q_diag",
        type=_float_list,
        default=None,
        metavar="Q1,Q2,..",
        help="diagonal of the state weight, one value or one per state (default: the system's Q)",
    )
    m.add_argument(
        "--R",
        dest="r_diag",
        type=_float_list,
        default=None,
        metavar="R1,R2,..",
        help="diagonal of the input weight, one value or one per input (default: the system's R)",
    )
    m.add_argument(
        "--rho",
        type=any_float,
        default=None,
        metavar="X",
        help="rho of the ultimate bound, > 0 (default: the level-set ball through x0)",
    )


def _add_loop_options(loop: argparse._ArgumentGroup, base: SweepConfig) -> None:
    """The closed loop's process noise and state feedback quantizer, then the loop settings, in group ``loop``."""
    loop.add_argument(
        "--disturbance",
        type=_disturbance_spec,
        default=(0.0, "gaussian"),
        metavar="SIGMA[:gaussian|uniform]",
        help="process noise of standard deviation SIGMA added to the true plant in the closed loop "
        "(the same draws for every b, estimator and the true-model loop; default: 0)",
    )
    loop.add_argument(
        "--feedback-bits",
        type=_feedback_bits,
        default=None,
        metavar="B|none",
        help="the MPC measures the state through a B-bit quantizer with subtractive dither over the "
        "training data's range (default: none, exact state)",
    )
    add_setting_options(loop, _LOOP, base)


def add_running_options(p: argparse.ArgumentParser) -> None:
    r = p.add_argument_group("running")
    r.add_argument(
        "--workers",
        type=pos_int,
        default=1,
        metavar="N",
        help="processes (N > 1 starts N worker processes; at most the machine's CPU count; default: 1, in-process)",
    )
    r.add_argument(
        "--threads",
        type=pos_int,
        default=2,
        metavar="N",
        help="threads of an in-process run (--workers 1): the compiled kernels run beside each other "
        "without the GIL, with the same results (default: 2, at most the CPU count; "
        "1: one thread)",
    )
    r.add_argument(
        "--dask",
        metavar="SPEC",
        default=None,
        help="run on dask.distributed: 'local' or 'local:N' (a LocalCluster of N worker processes "
        "here) or 'tcp://HOST:PORT' (a running 'dask scheduler'); needs the 'distributed' package",
    )
    r.add_argument("-q", "--quiet", action="store_true", help="no progress on stderr")


def build_parser(commands: Mapping[str, ModuleType], only: str | None = "*") -> argparse.ArgumentParser:
    """The ``qsid`` parser with one subcommand per module in ``commands`` (errors raise :class:`UsageError`).

    Each module has ``HELP``, ``DESCRIPTION`` and ``add_arguments(parser)``. Only the options of command
    ``only`` are built ("*": all; None: none, enough for ``qsid --help``), so a cold start loads only
    what that command needs.
    """
    parser = _Parser(
        prog=PROG,
        description="Quantized system identification and the MPC built on it (the QSID-MPC letter).",
    )
    parser.add_argument("--version", action="store_true", help="print the qsid version and exit")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name, mod in commands.items():
        sp = sub.add_parser(name, help=mod.HELP, description=mod.DESCRIPTION)
        if only == "*" or only == name:
            mod.add_arguments(sp)
    return parser


def add_quantizer_options(q: argparse._ArgumentGroup, q0: Any, range_help: str) -> None:
    """``--dither``, ``--range``, ``--guard`` (from the settings table) and ``--limits`` in the group ``q``
    (defaults from the engine's ``QuantizerSpec`` ``q0``); ``range_help`` says what the range means for this
    command."""
    add_setting_options(q, "quantizer", q0, {"range_mode": range_help})
    q.add_argument(
        "--limits",
        type=_limits,
        default=None,
        metavar="LO,HI[;LO,HI...]",
        help="the fixed range (with --range fixed): one pair for every channel, or one pair per "
        "channel, states then inputs",
    )
