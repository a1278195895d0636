"""The one colour palette of qsid: plots (hex strings) and the 3-D scene (RGB bytes) read it.

LS is blue, BCLS red, the true model black, everywhere: in the dashboard's plots
and 3-D phase portrait, and in the figures ``qsid reproduce`` writes.
"""

from __future__ import annotations

__all__ = ["COLORS", "EXTRA", "PINNED", "color", "pinned_color", "rgb", "vertex_rgb"]

#: Named colours (hex): estimators, the true model, theory curves, reference lines.
COLORS = {
    "LS": "#1f77b4",  # blue
    "BCLS": "#d62728",  # red
    "true": "#000000",  # black
    "theory": "#2ca02c",  # green: Theorem 1, the bound delta(eps)
    "ref": "#7f7f7f",  # grey: the -0.301/bit reference line
    "marker": "#444444",  # the dotted current-b marker
    "axes": "#969696",  # 3-D axes
    "bound": "#2ca02c",  # 3-D bound sphere
    "bound_capped": "#ff7f0e",  # 3-D bound sphere drawn capped (larger than the view)
    "realized": "#9467bd",  # purple: the a-posteriori bound (each realization's own model error and P)
    "unit_circle": "#bbbbbb",
}
#: A pinned (earlier) result's colour for each live colour: the same hue family, clearly another colour
#: (LS blue -> teal, BCLS red -> brown, ...), so live and pinned curves are told apart without the legend.
PINNED = {
    "#1f77b4": "#17becf",
    "#d62728": "#8c564b",
    "#9467bd": "#e377c2",
    "#ff7f0e": "#bcbd22",
    "#000000": "#7f7f7f",
    "#2ca02c": "#98df8a",
}
#: Colours for further series (labels without a named colour), in order.
EXTRA = ("#1f77b4", "#d62728", "#9467bd", "#ff7f0e")


def color(label: str, i: int = 0) -> str:
    """Hex colour of series ``label`` (the ``i``-th series if the label has no named colour)."""
    return COLORS.get(label, EXTRA[i % len(EXTRA)])


def pinned_color(live: str) -> str:
    """The colour of a pinned curve whose live curve is drawn in ``live`` (hex; unknown colours: dark grey)."""
    return PINNED.get(str(live).lower(), "#555555")


def rgb(label: str, i: int = 0) -> tuple[int, int, int]:
    """The same colour as :func:`color`, as an (r, g, b) tuple of 0..255 (for viser scene nodes)."""
    h = color(label, i).lstrip("#")
    return (int(h[0:2], 16), int(h[2:4], 16), int(h[4:6], 16))


def _to_linear(c: int) -> int:
    """One sRGB channel (0..255) -> linear light (0..255), the standard sRGB transfer function."""
    x = c / 255.0
    lin = x / 12.92 if x <= 0.04045 else ((x + 0.055) / 1.055) ** 2.4
    return int(round(255.0 * lin))


def vertex_rgb(label: str, i: int = 0) -> tuple[int, int, int]:
    """:func:`rgb` for per-vertex colours of viser scene nodes (e.g. line segments).

    viser hands per-vertex colours to three.js as linear light, which the screen
    shows gamma-encoded (lighter: the palette's LS blue came out teal). Converting
    the palette's sRGB colour to linear first makes the screen show the palette
    colour. Uniform node colours (one RGB for the whole node) are taken as sRGB
    by viser and use :func:`rgb` as is.
    """
    return tuple(_to_linear(c) for c in rgb(label, i))  # type: ignore[return-value]
