"""The letter's uniform quantizer, subtractive dither, and quantizer ranges.

Quantizer (letter, Section III): over ``[lo, hi]`` with ``2**b`` cells of width
``eps = (hi - lo) / 2**b`` and output levels ``lo + eps/2 + k*eps`` for
``k = 0 .. 2**b - 1``. The letter's formula ``lo + eps/2 + eps*floor((x-lo)/eps)``
would give a ``2**b + 1``-th level at ``x = hi``; the cell index is clamped to
``2**b - 1`` so there are exactly ``2**b`` levels. Inputs below ``lo`` (above
``hi``) map to the lowest (highest) level: that is *overload*.

Subtractive dither: ``x~ = Q(x + w) - w`` with ``w ~ U[-eps/2, eps/2]``. While
``x + w`` stays inside ``[lo, hi]`` the error ``x - x~`` is exactly uniform on
``[-eps/2, eps/2]`` (variance ``eps**2/12``) and independent of ``x``.

Non-subtractive dither (``x~ = Q(x + w)``, the receiver needs no copy of ``w``):
with ``tpdf`` (``w`` the sum of two independent U[-eps/2, eps/2], triangular on
``[-eps, eps]``) the total error ``x~ - x`` has mean 0 and variance ``eps**2/4``
whatever ``x`` is, and is uncorrelated between samples (Gray & Stockham 1993;
Wannamaker, Lipshitz & Vanderkooy 2000): its first two moments are known, which
is all least squares and its bias compensation use. With ``rpdf`` (one uniform
draw) only the mean is signal-independent; the variance moves between 0 and
``eps**2/4`` with the signal's position in its cell (:data:`ERROR_VARIANCE`).

Guard band: the range is widened by the dither's amplitude on each side, ``[lo - eps/2,
hi + eps/2]`` with ``eps = (hi - lo) / (2**b - 1)`` (``[lo - eps, hi + eps]`` with
``eps = (hi - lo) / (2**b - 2)`` for ``tpdf``), so ``x + w`` can never leave it for
``x`` in ``[lo, hi]``: no overload, at the price of a slightly wider cell (at b = 1
``tpdf`` gets half a cell only, see :func:`guard_cells`).

The guard band is **on by default** (:class:`QuantizerSpec`): "no overload" is a
hypothesis of Theorem 1 and of bias-compensated LS. Without it, a range taken
from the data's own min/max makes ``x + w`` overload near the extremes (measured:
3.96 % of entries on the dc-motor at b = 2) and the error is no longer uniform or
independent of ``x``. The letter's own settings (per-channel data range, no
guard band) are :data:`LETTER_QUANTIZER`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ConfigError, check_choice, check_int
from ..validate import as_float_array, check_bool, check_quantizer_range, checked_signal

#: A word-length setting of some channels: None (the swept b), "exact" (not quantized), a word length for all,
#: or one entry per channel (a word length, "b" or "exact").
BitsSpec = str | int | Sequence[int | str] | None

__all__ = [
    "draw_unit_dither",
    "draw_dither_units",
    "DITHERS",
    "ERROR_VARIANCE",
    "bcls_reason",
    "guard_cells",
    "channel_bits",
    "channel_eps",
    "RANGE_MODES",
    "MAX_BITS",
    "QuantizerSpec",
    "LETTER_QUANTIZER",
    "Quantized",
    "cell_width",
    "quantize",
    "data_ranges",
    "effective_ranges",
]

DITHERS = ("subtractive", "tpdf", "rpdf", "none")
#: Variance of the total error ``x~ - x`` in units of ``eps**2`` where the theory gives one that does not
#: depend on the signal: subtractive uniform dither (error U[-eps/2, eps/2]) and non-subtractive triangular
#: (TPDF) dither of width 2 eps (error mean 0, variance eps**2/4: Gray & Stockham, "Dithered quantizers",
#: IEEE Trans. Inf. Theory 39(3), 1993; Wannamaker, Lipshitz & Vanderkooy, "A theory of nonsubtractive
#: dither", IEEE Trans. Signal Process. 48(2), 2000).
ERROR_VARIANCE = {"subtractive": 1.0 / 12.0, "tpdf": 1.0 / 4.0}
_NO_VARIANCE = {
    "rpdf": "non-subtractive uniform (RPDF) dither makes the error's mean signal-independent but not its "
    "variance (between 0 and eps^2/4 depending on where the signal sits in its cell), so no known D exists",
    "none": "without dither the error is a deterministic function of the signal, not noise of known variance",
}
#: Nominal eps-units variance used where no known one exists (the plain quantizer's eps^2/12)
NOMINAL_VARIANCE = 1.0 / 12.0
RANGE_MODES = ("per-channel", "shared", "fixed")
MAX_BITS = 32


@dataclass(frozen=True)
class QuantizerSpec:
    """How data are quantized (everything except the word length, which is swept).

    Parameters
    ----------
    dither : {"subtractive", "tpdf", "rpdf", "none"}
        ``subtractive``: ``Q(x + w) - w`` with ``w ~ U[-eps/2, eps/2]`` (the letter's);
        ``tpdf``: ``Q(x + w)`` with ``w`` the sum of two independent U[-eps/2, eps/2]
        (triangular on [-eps, eps]), not subtracted; ``rpdf``: ``Q(x + w)`` with
        ``w ~ U[-eps/2, eps/2]``, not subtracted; ``none``: ``Q(x)``.
    range_mode : {"per-channel", "shared", "fixed"}
        ``per-channel``: min/max of each state and input channel over the data;
        ``shared``: one range over all channels (Theorem 1's single-eps setting);
        ``fixed``: the given ``fixed_range``.
    guard : bool, default True
        Widen the range by the dither's amplitude on each side (eps/2; eps for
        ``tpdf``) so that ``x + w`` never overloads (for data inside the range). On by default because Theorem 1 and BCLS
        assume no overload; :data:`LETTER_QUANTIZER` has it off, as the letter.
    fixed_range : tuple of (lo, hi), or sequence of per-channel (lo, hi)
        Needed when ``range_mode == "fixed"``; a single pair applies to every
        channel, else one pair per channel (n states then m inputs).
    """

    dither: str = "subtractive"
    range_mode: str = "per-channel"
    guard: bool = True
    fixed_range: tuple[Any, ...] | None = None

    def __post_init__(self) -> None:
        check_choice("dither", self.dither, DITHERS)
        check_choice("range", self.range_mode, RANGE_MODES)
        object.__setattr__(self, "guard", check_bool("guard", self.guard))
        if self.range_mode == "fixed" and self.fixed_range is None:
            raise ConfigError("range 'fixed' needs fixed_range=(lo, hi) or one (lo, hi) per channel")
        if self.fixed_range is not None:
            fr = as_float_array("fixed_range", self.fixed_range, ndim_max=2, max_abs=None)
            if fr.shape == (2,):
                fr = fr[None, :]
            if fr.ndim != 2 or fr.shape[1] != 2 or np.any(fr[:, 1] <= fr[:, 0]):
                raise ConfigError("fixed_range must be (lo, hi) with lo < hi, or a list of such pairs per channel")
            check_quantizer_range("fixed_range", fr[:, 0], fr[:, 1])
            object.__setattr__(self, "fixed_range", tuple(map(tuple, fr.tolist())))
        if not isinstance(self.guard, (bool, np.bool_)):
            raise ConfigError(f"guard must be True or False; got {self.guard!r}")
        object.__setattr__(self, "guard", bool(self.guard))


_GUARD_DEFAULT: bool = QuantizerSpec.guard  # one source of truth for the default

#: The letter's quantizer (Section V): subtractive dither, per-channel range from the
#: data's min/max, **no** guard band (so some entries overload at low b).
LETTER_QUANTIZER = QuantizerSpec(dither="subtractive", range_mode="per-channel", guard=False)


def guard_cells(dither: str, guard: bool, bits: int | None = None) -> float:
    """Guard band on each side, in cells: the dither's amplitude (1/2; 1 for ``tpdf``), or 0 without guard.

    At b = 1 two levels leave no room for one cell on each side: ``tpdf`` then gets half a
    cell, like the other kinds, and may overload (the overload is measured and reported).
    """
    if not guard:
        return 0.0
    return 1.0 if dither == "tpdf" and (bits is None or bits >= 2) else 0.5


def bcls_reason(dither: str) -> str:
    """Why BCLS has no known noise variance with this dither ("" when it has one, see :data:`ERROR_VARIANCE`)."""
    check_choice("dither", dither, DITHERS)
    return _NO_VARIANCE.get(dither, "")


def _entry(v: int | str, bits: int) -> int | None:
    """One per-channel entry: ``"b"`` (the swept word length), ``"exact"`` (None: not quantized) or an int."""
    if isinstance(v, str):
        return int(bits) if v == "b" else None
    return int(v)


def channel_bits(
    bits: int, n: int, m: int, input_bits: BitsSpec = None, state_bits: Sequence[int | str] | None = None
) -> tuple[int | None, ...]:
    """Word length of every channel (n states, then m inputs) at the swept word length ``bits``.

    Parameters
    ----------
    bits : int
        The swept word length.
    n, m : int
        Numbers of states and inputs.
    input_bits : None, "exact", int or tuple of m entries
        None: the inputs have ``bits`` too; "exact": inputs recorded without
        quantization; an int: every input; a tuple: one entry per input, each an
        int, ``"exact"`` or ``"b"`` (the swept word length).
    state_bits : None or tuple of 1 or n entries
        None: every state has ``bits``; else one entry for every state or one per state, as for the inputs.

    Returns
    -------
    tuple of length n + m: int, or None for a channel recorded exactly.

    Raises
    ------
    ConfigError
        If a tuple does not have one entry per input (state).
    """
    ins: list[int | None]
    if input_bits is None:
        ins = [int(bits)] * m
    elif isinstance(input_bits, str):
        ins = [None] * m
    elif isinstance(input_bits, (int, np.integer)):
        ins = [int(input_bits)] * m
    else:
        if len(input_bits) != m:
            raise ConfigError(
                f"input_bits has {len(input_bits)} entries; the system has {m} input(s): give one "
                "word length (or 'exact') for all, or one per input"
            )
        ins = [_entry(v, bits) for v in input_bits]
    sts: list[int | None]
    if state_bits is None:
        sts = [int(bits)] * n
    elif len(state_bits) == 1:
        sts = [_entry(state_bits[0], bits)] * n
    else:
        if len(state_bits) != n:
            raise ConfigError(
                f"state_bits has {len(state_bits)} entries; the system has {n} state(s): give one "
                "entry for all or one per state ('b' = the swept b, a word length, or 'exact')"
            )
        sts = [_entry(v, bits) for v in state_bits]
    return tuple(sts + ins)


def channel_eps(
    lo: np.ndarray, hi: np.ndarray, chan_bits: Sequence[int | None], guard: bool, dither: str
) -> np.ndarray:
    """Cell width per channel, shape (p,), for word lengths ``chan_bits`` (:func:`channel_bits`); 0 where exact."""
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    out = np.zeros(len(chan_bits))
    for a, b in enumerate(chan_bits):
        if b is not None:
            out[a] = cell_width(lo[a], hi[a], b, guard, dither)
    return out


def cell_width(
    lo: np.ndarray | float, hi: np.ndarray | float, bits: int, guard: bool = _GUARD_DEFAULT, dither: str = "subtractive"
) -> np.ndarray:
    """Cell width eps for ``bits`` bits over ``[lo, hi]``: ``(hi-lo)/(2**b - 2 g)``, ``g`` = :func:`guard_cells`."""
    bits = check_int("bits", bits, 1, MAX_BITS)
    cells = 2.0**bits - 2.0 * guard_cells(dither, guard, bits)
    width: np.ndarray = (np.asarray(hi, dtype=float) - np.asarray(lo, dtype=float)) / cells
    return width


def effective_ranges(
    lo: np.ndarray, hi: np.ndarray, bits: int, guard: bool, dither: str = "subtractive"
) -> tuple[np.ndarray, np.ndarray]:
    """The quantizer's actual lower bound and cell width per channel, ``(lo_q, eps)``.

    ``lo_q = lo - g eps`` with ``g`` = :func:`guard_cells` (0 without guard band).
    The quantizer covers ``[lo_q, lo_q + 2**b * eps]``, symmetric about ``(lo + hi)/2``.
    """
    eps = cell_width(lo, hi, bits, guard, dither)
    lo_q = np.asarray(lo, dtype=float) - guard_cells(dither, guard, bits) * eps
    return lo_q, eps


@dataclass
class Quantized:
    """Result of :func:`quantize`.

    Attributes
    ----------
    values : ndarray
        The reconstructed signal ``x~`` (same shape as the input).
    eps : ndarray
        Cell width per channel (last axis), or a scalar array.
    overload : ndarray of bool
        Where ``x + w`` fell outside the quantizer range.
    """

    values: np.ndarray
    eps: np.ndarray
    overload: np.ndarray

    @property
    def overload_fraction(self) -> float:
        return float(self.overload.mean()) if self.overload.size else 0.0


def draw_unit_dither(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    """U[-1/2, 1/2) draws, bit for bit ``rng.uniform(-0.5, 0.5, shape)`` (which is ``-0.5 + 1.0 * r``), ~35 % faster.

    The one source of unit dither draws: the explicit quantizer here and the fused kernel's
    chunks (:mod:`qsid_core.quantization.moments`) consume the generator the same way.
    """
    u = rng.random(size=shape)
    u -= 0.5
    return u


def draw_dither_units(rng: np.random.Generator, shape: tuple[int, ...], dither: str) -> np.ndarray | None:
    """The dither in cell units for one block of entries (None for ``none``).

    ``subtractive``/``rpdf``: one U[-1/2, 1/2) draw per entry; ``tpdf``: the sum of two
    (triangular on [-1, 1]), the second block drawn after the first.
    """
    if dither == "none":
        return None
    u = draw_unit_dither(rng, shape)
    if dither == "tpdf":
        u += draw_unit_dither(rng, shape)
    return u


def quantize(
    x: np.ndarray,
    lo: np.ndarray | float,
    hi: np.ndarray | float,
    bits: int,
    *,
    dither: str = "subtractive",
    guard: bool = _GUARD_DEFAULT,
    rng: np.random.Generator | None = None,
    unit_dither: np.ndarray | None = None,
) -> Quantized:
    """Quantize ``x`` with the letter's quantizer, optionally with subtractive dither.

    Parameters
    ----------
    x : ndarray, shape (..., c)
        Signal; ``lo`` and ``hi`` broadcast against it (per channel = last axis).
    lo, hi : float or ndarray, shape (c,)
        Data range; ``hi > lo``.
    bits : int, 1..32
        Word length b; the quantizer has exactly ``2**b`` levels.
    dither : {"subtractive", "tpdf", "rpdf", "none"}
        See :class:`QuantizerSpec`.
    guard : bool, default True (as :class:`QuantizerSpec`)
        Widen the range by the dither's amplitude on each side (see module docstring).
    rng : numpy Generator, optional
        Source of the dither when ``unit_dither`` is not given (:func:`draw_dither_units`).
    unit_dither : ndarray, same shape as x, optional
        The dither in cell units (U[-1/2, 1/2]; triangular on [-1, 1] for ``tpdf``);
        the dither is ``eps * unit_dither`` (lets a caller reuse the same draws across
        word lengths).

    Returns
    -------
    Quantized
    """
    check_choice("dither", dither, DITHERS)
    bits = check_int("bits", bits, 1, MAX_BITS)
    guard = check_bool("guard", guard)
    x, lo_a, hi_a = checked_signal(x, lo, hi, unit_dither, rng)
    lo_q, eps = effective_ranges(lo_a, hi_a, bits, guard, dither)
    if dither != "none":
        if unit_dither is None:
            unit_dither = draw_dither_units(rng if rng is not None else np.random.default_rng(), x.shape, dither)
        w = eps * np.asarray(unit_dither, dtype=float)
    else:
        w = np.zeros_like(x)
    levels = 2.0**bits
    s = (x + w - lo_q) / eps
    overload = (s < 0) | (s > levels)
    k = np.clip(np.floor(s), 0, levels - 1)
    values = lo_q + eps * (k + 0.5) - (w if dither == "subtractive" else 0.0)
    return Quantized(values=values, eps=np.asarray(eps), overload=overload)


def data_ranges(states: np.ndarray, inputs: np.ndarray, spec: QuantizerSpec) -> tuple[np.ndarray, np.ndarray]:
    """Per-channel data range ``(lo, hi)``, each of shape (n + m,), for the given spec.

    ``states`` has shape (..., n) and ``inputs`` (..., m). A channel whose data are
    constant gets a tiny symmetric range around its value so eps stays positive.
    """
    n, m = states.shape[-1], inputs.shape[-1]
    if spec.range_mode == "fixed":
        fr = np.asarray(spec.fixed_range, dtype=float)
        if fr.shape[0] == 1:
            fr = np.repeat(fr, n + m, axis=0)
        if fr.shape[0] != n + m:
            raise ConfigError(
                f"fixed_range has {fr.shape[0]} pairs; give one pair or one per channel ({n} states + {m} inputs)"
            )
        return fr[:, 0].copy(), fr[:, 1].copy()
    # one column at a time: a strided 1-D reduction is several times faster than reducing a tall array along axis 0
    cols = [c[:, i] for c in (states.reshape(-1, n), inputs.reshape(-1, m)) for i in range(c.shape[1])]
    lo = np.array([c.min() for c in cols], dtype=float)
    hi = np.array([c.max() for c in cols], dtype=float)
    if spec.range_mode == "shared":
        lo = np.full(n + m, lo.min())
        hi = np.full(n + m, hi.max())
    flat = hi - lo <= 0
    if np.any(flat):
        pad = np.maximum(np.abs(lo[flat]), 1.0) * 1e-9
        lo[flat] -= pad
        hi[flat] += pad
    return lo, hi
