"""Quantization: the quantizer and its dither, and the Gram matrices of quantized data for many word lengths at once (compiled kernels).

Every public name of this subpackage is listed in ``__all__``; import from here, not from its modules."""

from __future__ import annotations

from .moments import CHUNK_ROWS, ENGINES, Moments, PreparedData, exact_moments, prepare, quantized_moments
from .quantize import (
    DITHERS,
    ERROR_VARIANCE,
    LETTER_QUANTIZER,
    MAX_BITS,
    RANGE_MODES,
    Quantized,
    QuantizerSpec,
    bcls_reason,
    cell_width,
    channel_bits,
    channel_eps,
    data_ranges,
    draw_dither_units,
    draw_unit_dither,
    effective_ranges,
    guard_cells,
    quantize,
)
from .quantizer_demo import CELL_BINS, SCATTER_POINTS, QuantizerDemo, channel_demo, quantizer_demo

__all__ = [
    "CELL_BINS",
    "CHUNK_ROWS",
    "DITHERS",
    "ENGINES",
    "ERROR_VARIANCE",
    "LETTER_QUANTIZER",
    "MAX_BITS",
    "Moments",
    "PreparedData",
    "Quantized",
    "QuantizerDemo",
    "QuantizerSpec",
    "RANGE_MODES",
    "SCATTER_POINTS",
    "bcls_reason",
    "cell_width",
    "channel_bits",
    "channel_demo",
    "channel_eps",
    "data_ranges",
    "draw_dither_units",
    "draw_unit_dither",
    "effective_ranges",
    "exact_moments",
    "guard_cells",
    "prepare",
    "quantize",
    "quantized_moments",
    "quantizer_demo",
]
