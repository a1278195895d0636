"""What a dashboard view is: a name, a plot shape, when it changes, and a builder.

A *frame* (:class:`app.dashboard.frames.Frame`) is what a browser tab knows at
one moment; a view reads only these attributes of it: ``series()`` (label ->
rows of every b computed so far), ``bits`` (the current word length),
``true_cost``, ``labels``, ``idents`` (label -> identified models at the current
b), ``system``, ``loops``/``true_loop`` (closed loops at the current b), ``ex``
(the engine's cached :class:`~qsid_core.experiment.Experiment`), ``pinned`` (a
pinned earlier frame or None) and ``datalength`` (a finished data-length study
for the current settings, or None).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import plotly.graph_objects as go

__all__ = ["View", "CURVES", "CURRENT"]

#: The view draws every b (rebuilt when rows change; a b change only moves its marker).
CURVES = "curves"
#: The view draws the current b only (rebuilt when b or the models at b change).
CURRENT = "current"


@dataclass(frozen=True)
class View:
    """One plot of the dashboard.

    Attributes
    ----------
    name : str
        Key of the plot (unique).
    aspect : float
        Height / width of the plot in the panel.
    depends : {"curves", "current"}
        What makes it redraw (:data:`CURVES` or :data:`CURRENT`).
    build : callable(frame) -> plotly.graph_objects.Figure
        Pure: the figure for a frame.
    tab : str
        Tab of the plots panel the view sits in (tabs appear in registry order).
    key : callable(frame) -> hashable, optional
        For a ``"current"`` view: what it reads; rebuilt when this changes
        (default: b and the identified models).
    """

    name: str
    aspect: float
    depends: str
    build: Callable[[Any], go.Figure]
    tab: str = "Identification"
    key: Callable[[Any], Any] | None = None
