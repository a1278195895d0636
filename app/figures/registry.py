"""The dashboard's plots, in panel order. Adding a view = one new module + one line here.

Each module defines ``VIEW`` (:class:`app.figures.view.View`); the dashboard
creates one plot per entry and redraws it through the entry's ``build``.
"""

from __future__ import annotations

from dataclasses import replace

from . import (
    bandwidth,
    bits_needed,
    bound,
    compare,
    cost,
    datalength,
    eigenvalues,
    error_vs_bits,
    koopman_eigen,
    koopman_error,
    koopman_outcomes,
    koopman_prediction,
    norm_time,
    quantizer,
    residual,
    time_series,
)
from .view import View

__all__ = ["TABS", "VIEWS", "KOOPMAN_TABS", "KOOPMAN_VIEWS", "ALL_VIEWS", "view_names"]

#: Tabs of the plots panel, in order (a view's ``tab``); the current-b views come first in each tab.
TABS = ("Identification", "Control", "Quantizer", "Data length", "Bandwidth", "Compare")

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
    bandwidth.VIEW,
    compare.VIEW,
)

#: The plots panel's group of a nonlinear plant (shown instead of :data:`TABS` while one is picked).
KOOPMAN_TABS = ("Nonlinear",)
#: Its views (they read a :class:`~app.dashboard.frames.KoopmanFrame`), in panel order.
KOOPMAN_VIEWS: tuple[View, ...] = (
    koopman_error.VIEW,
    koopman_eigen.VIEW,
    koopman_prediction.VIEW,
    koopman_outcomes.VIEW,
    bandwidth.KOOPMAN_VIEW,
)
#: Every view the plots panel holds.
ALL_VIEWS: tuple[View, ...] = VIEWS + KOOPMAN_VIEWS


def view_names() -> tuple[str, ...]:
    """Every plot the plots panel holds (the linear views, then the nonlinear plants')."""
    return tuple(v.name for v in ALL_VIEWS)
