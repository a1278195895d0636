"""The dashboard's plots, in panel order. Adding a view = one new module + one line here.

Each module defines ``VIEW`` (:class:`app.figures.view.View`); the dashboard
creates one plot per entry and redraws it through the entry's ``build``.
"""

from __future__ import annotations

from dataclasses import replace

from . import (
    bits_needed,
    bound,
    compare,
    cost,
    datalength,
    eigenvalues,
    error_vs_bits,
    norm_time,
    quantizer,
    residual,
    time_series,
)
from .view import View

__all__ = ["TABS", "VIEWS", "view_names"]

#: Tabs of the plots panel, in order (a view's ``tab``); the current-b views come first in each tab.
TABS = ("Identification", "Control", "Quantizer", "Data length", "Compare")

VIEWS: tuple[View, ...] = (
    error_vs_bits.VIEW,
    eigenvalues.VIEW,
    time_series.VIEW,
    replace(cost.VIEW, tab="Control"),
    bits_needed.VIEW,
    replace(bound.VIEW, tab="Control"),
    replace(norm_time.VIEW, tab="Control"),
    residual.VIEW,
    quantizer.VIEW,
    datalength.VIEW,
    compare.VIEW,
)


def view_names() -> tuple[str, ...]:
    return tuple(v.name for v in VIEWS)
