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
    loop_outcomes,
    norm_time,
    prediction_error,
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
#: Its views, offered when the result holds a lifting (they read a :class:`~app.frames.frame.KoopmanFrame`), in
#: panel order: the same quantities as the linear views where there is one (the error vs b, the eigenvalues), and
#: the views only a lifted model has (its prediction error, the Koopman MPC outcomes).
KOOPMAN_VIEWS: tuple[View, ...] = (
    error_vs_bits.LIFTED_VIEW,
    eigenvalues.LIFTED_VIEW,
    prediction_error.VIEW,
    loop_outcomes.VIEW,
    bandwidth.KOOPMAN_VIEW,
)
#: Every view the plots panel holds.
ALL_VIEWS: tuple[View, ...] = VIEWS + KOOPMAN_VIEWS


def view_names() -> tuple[str, ...]:
    """Every plot the plots panel holds (the linear views, then the nonlinear plants')."""
    return tuple(v.name for v in ALL_VIEWS)
