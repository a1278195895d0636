"""The ``qsid`` argument parser: value types, the options every run shares, one-line errors.

Defaults and choices are the engine's (``SweepConfig()``, ``MPCConfig()``,
``QuantizerSpec()``, ``DITHERS``, ``RANGE_MODES``, ``ESTIMATORS``); nothing is typed twice.
Each command adds its own options (``add_arguments`` in its module).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable, Iterable, Mapping
from types import ModuleType, SimpleNamespace
from typing import TYPE_CHECKING, Any, NoReturn

if TYPE_CHECKING:
    from qsid_core import SweepConfig

__all__ = [
    "PROG",
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


def engine() -> SimpleNamespace:
    """The engine's defaults and choices, imported on first use (``qsid --help`` never loads numpy).

    Returns a namespace with ``sweep`` (``SweepConfig(mpc=None)``), ``mpc`` (``MPCConfig()``), ``quant``
    (``QuantizerSpec()``), ``letter`` (``SweepConfig.letter()``), ``dithers``, ``range_modes`` (all of the
    engine's; "fixed" needs --limits) and ``estimators``.
    """
    global _ENGINE
    if _ENGINE is None:
        from qsid_core import MPCConfig, QuantizerSpec, SweepConfig
        from qsid_core.identification import ESTIMATORS
        from qsid_core.quantization import DITHERS, RANGE_MODES

        _ENGINE = SimpleNamespace(
            sweep=SweepConfig(mpc=None),
            mpc=MPCConfig(),
            quant=QuantizerSpec(),
            letter=SweepConfig.letter(mpc=None),
            dithers=DITHERS,
            range_modes=RANGE_MODES,
            estimators=ESTIMATORS,
        )
    return _ENGINE


_ENGINE: SimpleNamespace | None = None


class UsageError(Exception):
    """A bad command line (reported as one line, exit code 2)."""


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one line (raised, so ``main(argv)`` can return 2)."""

    def error(self, message: str) -> NoReturn:
        if message.endswith("expected one argument"):
            message += " (a value that starts with '-' needs '=', e.g. --limits=-20,20 or --x0=-1,0,0)"
        raise UsageError(message)


def _int_type(name: str, lo: int) -> Callable[[str], int]:
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


def limits_spec(pairs: Iterable[tuple[float, float]]) -> str:
    """Fixed ranges as the ``--limits`` text (inverse of the parser's type)."""
    return ";".join(f"{lo!r},{hi!r}" for lo, hi in pairs)


def floats_spec(values: Iterable[float]) -> str:
    """Numbers as a comma list, exactly (``repr``), for the command a dashboard shows."""
    return ",".join(repr(float(v)) for v in values)


pos_int = _int_type("positive integer", 1)
_nonneg_int = _int_type("non-negative integer", 0)


def bits_spec(bits: Iterable[int]) -> str:
    """Word lengths as the ``--bits`` text (``(1, ..., 16)`` -> ``"1:16"``)."""
    b = list(bits)
    if len(b) > 1 and b == list(range(b[0], b[-1] + 1)):
        return f"{b[0]}:{b[-1]}"
    return ",".join(map(str, b))


def _g(v: float) -> str:
    return format(v, "g")


def _onoff(v: bool) -> str:
    return "on" if v else "off"


def add_data_options(p: argparse.ArgumentParser, base: SweepConfig | None = None, seed: bool = True) -> None:
    """System, data and quantizer options; defaults from ``base`` (a SweepConfig; default the engine's)."""
    e = engine()
    base = e.sweep if base is None else base
    q0 = base.quantizer
    bits_default = bits_spec(base.bits)
    g = p.add_argument_group("system and data")
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
    g.add_argument(
        "--realizations",
        type=pos_int,
        default=base.realizations,
        metavar="N",
        help=f"dither realizations per word length (default: {base.realizations})",
    )
    g.add_argument(
        "--trajectories",
        type=pos_int,
        default=base.trajectories,
        metavar="N",
        help=f"simulated trajectories (default: {base.trajectories})",
    )
    g.add_argument(
        "--steps", type=pos_int, default=base.steps, metavar="N", help=f"samples per trajectory (default: {base.steps})"
    )
    g.add_argument(
        "--input-amplitude",
        type=_float_type,
        default=base.input_amplitude,
        metavar="A",
        help=f"training inputs u ~ U[-A, A] (default: {_g(base.input_amplitude)}, the letter's)",
    )
    if seed:
        g.add_argument(
            "--seed",
            type=_nonneg_int,
            default=None,
            metavar="N",
            help="seed of both the data and the dither streams (sets --data-seed and --dither-seed)",
        )
    g.add_argument(
        "--data-seed",
        type=_nonneg_int,
        default=None,
        metavar="N",
        help=f"seed of the simulated data (default: {base.data_seed})",
    )
    g.add_argument(
        "--dither-seed",
        type=_nonneg_int,
        default=None,
        metavar="N",
        help=f"seed of the dither streams (default: {base.dither_seed})",
    )
    q = p.add_argument_group("quantizer and identification")
    add_quantizer_options(q, q0, "quantizer range: min/max per channel, one range for all, or fixed (--limits)")
    q.add_argument(
        "--estimator",
        choices=e.estimators,
        default=base.estimator,
        help=f"least squares or bias-compensated LS (default: {base.estimator})",
    )


def add_run_options(p: argparse.ArgumentParser, base: SweepConfig | None = None) -> None:
    """Options shared by ``sweep`` and ``reproduce`` (defaults from ``base``: the engine's or the letter's)."""
    e = engine()
    base = e.sweep if base is None else base
    mpc = e.mpc
    add_data_options(p, base)
    x = p.add_argument_group("what-ifs: word length per channel, sensor noise, a saved study")
    x.add_argument(
        "--input-bits",
        default=None,
        metavar="B|exact|B1,B2,..",
        help="word length of the inputs: one for all, one per input ('8,exact'), or 'exact' (inputs "
        "recorded without quantization); --bits then sweeps the states (default: same as --bits)",
    )
    x.add_argument(
        "--state-bits",
        default=None,
        metavar="E|E1,E2,..",
        help="word length of the states, one entry for all or one per state: 'b' (the swept --bits), "
        "a fixed word length, or 'exact' (not quantized), e.g. 'b,b,12,exact' (default: all b)",
    )
    x.add_argument(
        "--noise",
        default=None,
        metavar="SIGMA|S1,S2,..",
        help="standard deviation of Gaussian sensor noise added to the recorded states before "
        "quantization, one for all or one per state (seeded by the data seed; default: 0)",
    )
    x.add_argument(
        "--noise-known",
        action="store_true",
        help="BCLS adds the noise variance sigma^2 to D (without it BCLS corrects only the "
        "quantization noise it knows of)",
    )
    m = p.add_argument_group("MPC and ultimate bound")
    m.add_argument(
        "--horizon", type=pos_int, default=mpc.horizon, metavar="N", help=f"MPC horizon (default: {mpc.horizon})"
    )
    m.add_argument(
        "--mpc-steps",
        type=pos_int,
        default=mpc.steps,
        metavar="N",
        help=f"closed-loop steps on the true system (default: {mpc.steps})",
    )
    m.add_argument(
        "--u-max",
        type=_floats_type,
        default=mpc.u_max,
        metavar="X",
        help="input bound |u_i| <= X; one value or one per input, comma-separated "
        f"(default: {','.join(map(_g, mpc.u_max))})",
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
        "--reference",
        default=None,
        metavar="SPEC|FILE.csv",
        help="time-varying reference the MPC tracks with preview: step:STATE:AMPLITUDE:TIME, "
        "sine:STATE:AMPLITUDE:PERIOD, square:STATE:AMPLITUDE:PERIOD (STATE a name or 1-based "
        "index, times in samples) or a CSV file with one row per step and one column per state; "
        "excludes --x-ref",
    )
    m.add_argument(
        "--tracking",
        choices=("letter", "offset-free"),
        default="letter",
        help="the cost's input term: the letter's u'Ru, or offset-free (u - u_ref)'R(u - u_ref) with "
        "u_ref = B^+ (I - A^) r, the input that holds the model at the reference (default: letter)",
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
    loop = p.add_argument_group("the real loop (disturbance and measurement)")
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
    loop.add_argument(
        "--feedback-noise",
        type=_nonneg_float,
        default=0.0,
        metavar="SIGMA",
        help="sensor noise (standard deviation) on that measurement (default: 0)",
    )
    loop.add_argument(
        "--loop-seed",
        type=_nonneg_int,
        default=0,
        metavar="N",
        help="seed of the disturbance, feedback dither and sensor noise (default: 0)",
    )
    m.add_argument(
        "--verify-steps",
        type=_nonneg_int,
        default=mpc.verify_steps,
        metavar="N",
        help="at most N closed-loop steps beyond --mpc-steps to decide whether a loop converges, stays "
        f"bounded or diverges on the true plant (default: {mpc.verify_steps}; 0: judge from the "
        "run alone where the spectral radius and the certificate decide, else call it bounded)",
    )
    m.add_argument(
        "--theta",
        type=_float_type,
        default=base.theta,
        metavar="X",
        help=f"theta of the ultimate bound, in (0, 1) (default: {_g(base.theta)})",
    )
    m.add_argument(
        "--rho",
        type=_float_type,
        default=None,
        metavar="X",
        help="rho of the ultimate bound, > 0 (default: the level-set ball through x0)",
    )
    add_running_options(p)


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
    """``--range``, ``--limits``, ``--guard`` and ``--dither`` in the group ``q`` (defaults from the
    engine's ``QuantizerSpec`` ``q0``); ``range_help`` says what the range means for this command."""
    e = engine()
    q.add_argument(
        "--range",
        dest="range_mode",
        choices=e.range_modes,
        default=q0.range_mode,
        help=f"{range_help} (default: {q0.range_mode})",
    )
    q.add_argument(
        "--limits",
        type=_limits,
        default=None,
        metavar="LO,HI[;LO,HI...]",
        help="the fixed range (with --range fixed): one pair for every channel, or one pair per "
        "channel, states then inputs",
    )
    q.add_argument(
        "--guard",
        action=argparse.BooleanOptionalAction,
        default=q0.guard,
        help="widen the range by the dither's amplitude on each side (half a cell; a cell for tpdf), "
        "so x + w never overloads "
        f"(default: {_onoff(q0.guard)})",
    )
    q.add_argument(
        "--dither",
        choices=e.dithers,
        default=q0.dither,
        help="subtractive uniform dither (the letter's), tpdf (non-subtractive triangular, width 2 eps: "
        "BCLS with D = eps^2/4), rpdf (non-subtractive uniform: BCLS not applicable) or none "
        f"(default: {q0.dither})",
    )
