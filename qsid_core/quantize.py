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

Guard band: the range is widened by half a cell on each side, ``[lo - eps/2,
hi + eps/2]`` with ``eps = (hi - lo) / (2**b - 1)``, so ``x + w`` can never leave
it for ``x`` in ``[lo, hi]``: no overload, at the price of a slightly wider cell.

The guard band is **on by default** (:class:`QuantizerSpec`): "no overload" is a
hypothesis of Theorem 1 and of bias-compensated LS. Without it, a range taken
from the data's own min/max makes ``x + w`` overload near the extremes (measured:
3.96 % of entries on the dc-motor at b = 2) and the error is no longer uniform or
independent of ``x``. The letter's own settings (per-channel data range, no
guard band) are :data:`LETTER_QUANTIZER`.
"""

from __future__ import annotations

from dataclasses import dataclass
import numpy as np

from .errors import ConfigError, check_choice, check_int
from .validate import as_float_array, check_bool, check_quantizer_range, checked_signal

__all__ = [
    "draw_unit_dither",
    "DITHERS",
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

DITHERS = ("subtractive", "none")
RANGE_MODES = ("per-channel", "shared", "fixed")
MAX_BITS = 32


@dataclass(frozen=True)
class QuantizerSpec:
    """How data are quantized (everything except the word length, which is swept).

    Parameters
    ----------
    dither : {"subtractive", "none"}
        Subtractive uniform dither, or plain quantization.
    range_mode : {"per-channel", "shared", "fixed"}
        ``per-channel``: min/max of each state and input channel over the data;
        ``shared``: one range over all channels (Theorem 1's single-eps setting);
        ``fixed``: the given ``fixed_range``.
    guard : bool, default True
        Widen the range by eps/2 on each side so that ``x + w`` never overloads
        (for data inside the range). On by default because Theorem 1 and BCLS
        assume no overload; :data:`LETTER_QUANTIZER` has it off, as the letter.
    fixed_range : tuple of (lo, hi), or sequence of per-channel (lo, hi)
        Needed when ``range_mode == "fixed"``; a single pair applies to every
        channel, else one pair per channel (n states then m inputs).
    """

    dither: str = "subtractive"
    range_mode: str = "per-channel"
    guard: bool = True
    fixed_range: tuple | None = None

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


def cell_width(lo: np.ndarray | float, hi: np.ndarray | float, bits: int, guard: bool = _GUARD_DEFAULT) -> np.ndarray:
    """Cell width eps for ``bits`` bits over ``[lo, hi]``: ``(hi-lo)/2**b``, or ``(hi-lo)/(2**b-1)`` with guard."""
    bits = check_int("bits", bits, 1, MAX_BITS)
    cells = 2.0**bits - (1.0 if guard else 0.0)
    return (np.asarray(hi, dtype=float) - np.asarray(lo, dtype=float)) / cells


def effective_ranges(lo: np.ndarray, hi: np.ndarray, bits: int, guard: bool) -> tuple[np.ndarray, np.ndarray]:
    """The quantizer's actual lower bound and cell width per channel, ``(lo_q, eps)``.

    Without guard band ``lo_q = lo``; with it ``lo_q = lo - eps/2``. In both cases
    the quantizer covers ``[lo_q, lo_q + 2**b * eps]``.
    """
    eps = cell_width(lo, hi, bits, guard)
    lo_q = np.asarray(lo, dtype=float) - (eps / 2 if guard else 0.0)
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


def draw_unit_dither(rng: np.random.Generator, shape: tuple) -> np.ndarray:
    """U[-1/2, 1/2) draws, bit for bit ``rng.uniform(-0.5, 0.5, shape)`` (which is ``-0.5 + 1.0 * r``), ~35 % faster.

    The one source of unit dither draws: the explicit quantizer here and the fused kernel's
    chunks (:mod:`qsid_core.moments`) consume the generator the same way.
    """
    u = rng.random(size=shape)
    u -= 0.5
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
    dither : {"subtractive", "none"}
    guard : bool, default True (as :class:`QuantizerSpec`)
        Widen the range by eps/2 on each side (see module docstring).
    rng : numpy Generator, optional
        Source of the dither when ``unit_dither`` is not given.
    unit_dither : ndarray, same shape as x, optional
        Draws from U[-1/2, 1/2]; the dither is ``eps * unit_dither`` (lets a
        caller reuse the same draws across word lengths).

    Returns
    -------
    Quantized
    """
    check_choice("dither", dither, DITHERS)
    bits = check_int("bits", bits, 1, MAX_BITS)
    guard = check_bool("guard", guard)
    x, lo_a, hi_a = checked_signal(x, lo, hi, unit_dither, rng)
    lo_q, eps = effective_ranges(lo_a, hi_a, bits, guard)
    if dither == "subtractive":
        if unit_dither is None:
            unit_dither = draw_unit_dither(rng if rng is not None else np.random.default_rng(), x.shape)
        w = eps * np.asarray(unit_dither, dtype=float)
    else:
        w = np.zeros_like(x)
    levels = 2.0**bits
    s = (x + w - lo_q) / eps
    overload = (s < 0) | (s > levels)
    k = np.clip(np.floor(s), 0, levels - 1)
    values = lo_q + eps * (k + 0.5) - w
    return Quantized(values=values, eps=np.asarray(eps), overload=overload)


def data_ranges(
    states: np.ndarray, inputs: np.ndarray, spec: QuantizerSpec
) -> tuple[np.ndarray, np.ndarray]:
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
    s2 = states.reshape(-1, n)
    u2 = inputs.reshape(-1, m)
    lo = np.concatenate([s2.min(axis=0), u2.min(axis=0)])
    hi = np.concatenate([s2.max(axis=0), u2.max(axis=0)])
    if spec.range_mode == "shared":
        lo = np.full(n + m, lo.min())
        hi = np.full(n + m, hi.max())
    flat = hi - lo <= 0
    if np.any(flat):
        pad = np.maximum(np.abs(lo[flat]), 1.0) * 1e-9
        lo[flat] -= pad
        hi[flat] += pad
    return lo, hi
