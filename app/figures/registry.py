"""The dashboard's plots, in panel order. Adding a view = one new module + one line here.

Each module defines ``VIEW`` (:class:`app.figures.view.View`); the dashboard
creates one plot per entry and redraws it through the entry's ``build``.
"""

from __future__ import annotations

from . import bound, cost, eigenvalues, error_vs_bits, norm_time
from .view import View

__all__ = ["VIEWS", "view_names"]

VIEWS: tuple[View, ...] = (
    error_vs_bits.VIEW,
    cost.VIEW,
    bound.VIEW,
    norm_time.VIEW,
    eigenvalues.VIEW,
)


def view_names() -> tuple[str, ...]:
    return tuple(v.name for v in VIEWS)
