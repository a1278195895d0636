"""What a dashboard view is: a name, a plot shape, when it changes, and a builder.

A *frame* (:class:`app.frames.frame.Frame`) is what a browser tab knows at
one moment; a view reads only these attributes of it: ``series()`` (label ->
rows of every b computed so far), ``bits`` (the current word length),
``true_cost``, ``labels``, ``idents`` (label -> identified models at the current
b), ``system``, ``loops``/``true_loop`` (closed loops at the current b), ``ex``
(the engine's cached :class:`~qsid_core.studies.experiment.Experiment`), ``pinned`` (a
pinned earlier frame or None) and ``datalength`` (a finished data-length study
for the current settings, or None).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

import plotly.graph_objects as go

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    from qsid_core import ClosedLoops, DataLengthResult, Experiment, LTISystem
    from qsid_core.studies import BitsIdentification, TheoryAtBits

__all__ = ["View", "FrameView", "CURVES", "CURRENT"]

#: The view draws every b (rebuilt when rows change; a b change only moves its marker).
CURVES = "curves"
#: The view draws the current b only (rebuilt when b or the models at b change).
CURRENT = "current"


class FrameView(Protocol):
    """The attributes of a frame the views read (:class:`app.frames.frame.Frame` has them).

    ``values`` are the tab's panel values (:class:`app.settings.values.Values`).
    """

    @property
    def values(self) -> Any: ...
    @property
    def system(self) -> LTISystem: ...
    @property
    def bits(self) -> int: ...
    @property
    def labels(self) -> tuple[str, ...]: ...
    @property
    def rows(self) -> Mapping[str, Mapping[int, Mapping[str, Any]]]: ...
    @property
    def done(self) -> int: ...
    @property
    def total(self) -> int: ...
    @property
    def loops(self) -> Mapping[str, ClosedLoops]: ...
    @property
    def true_loop(self) -> ClosedLoops | None: ...
    @property
    def theory(self) -> TheoryAtBits: ...
    @property
    def idents(self) -> Mapping[str, BitsIdentification]: ...
    @property
    def x0(self) -> NDArray[np.float64]: ...
    @property
    def ex(self) -> Experiment | None: ...
    @property
    def datalength(self) -> DataLengthResult | None: ...
    @property
    def complete(self) -> bool: ...
    @property
    def true_cost(self) -> float | None: ...
    def series(self) -> Mapping[str, list[dict[str, Any]]]: ...


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
