"""Views: pure functions from engine results to plotly figures (or 3-D scene arrays).

One module per view; :mod:`app.figures.registry` lists the dashboard's plots;
:func:`plot_results` draws finished sweeps (several on one figure) and
:func:`save_figure` writes PNG, SVG, PDF (offline, a local Chromium) or HTML;
:mod:`app.figures.palette` holds the colours every view (and the 3-D scene) uses.
"""

from .bound import bound_figure
from .cost import cost_figure
from .eigenvalues import eigen_figure
from .error_vs_bits import error_figure
from .export import save_figure
from .palette import COLORS
from .phase_portrait import phase_portrait_figure
from .results import plot_results
from .traces import move_current_bits

__all__ = [
    "COLORS",
    "error_figure",
    "cost_figure",
    "bound_figure",
    "eigen_figure",
    "phase_portrait_figure",
    "move_current_bits",
    "plot_results",
    "save_figure",
]
