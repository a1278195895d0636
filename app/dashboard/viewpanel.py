"""The plots panel of a tab: one group per :data:`app.figures.registry.TABS`, each with its views and their inputs.

The panel shows one group at a time, chosen in its "show" dropdown. The server owns that choice: a lesson
brings its group forward by setting the dropdown (:meth:`ViewPanel.show`), which hides the other groups'
elements through viser's public ``visible`` property. (viser has no server call that activates one of a
panel's client-side tabs, so the groups are not panel tabs; nothing is run in the page to press one.)

The views' own inputs live next to the views: the quantizer's channel, the word
lengths of the side-by-side portraits, the pin buttons (Compare) and the
data-length study's button and progress (Data length). Like the left panel's
inputs, a change only marks the tab dirty; :meth:`ViewPanel.values` gives the
:class:`~app.settings.values.Values` fields they set.

The plots' plotly.js: the "basic" bundle (scatter, bar, pie), 1.2 MB instead of 4.8 MB.

Before a tab's first plot, viser sends the plotly package's full ``plotly.min.js``
(4.8 MB) over the tab's websocket, and the browser evaluates it. Headless
Chromium here took ~1.3 s to evaluate the full bundle against ~0.2 s for
plotly.js's official "basic" bundle (the same version, only the trace types
scatter, bar and pie, which are all the dashboard draws; a test checks every
view's traces). :func:`send_basic_bundle` queues that bundle first and tells viser
it is there, so viser does not send its own.

The bundle (``assets/plotly-basic.min.js``, npm ``plotly.js-basic-dist-min``, MIT
licence beside it) is used only when its version equals the plotly.js version the
installed plotly package was built for; otherwise viser's own bundle is sent as before.
To update it: ``npm pack plotly.js-basic-dist-min@<plotly.offline.get_plotlyjs_version()>``.

Whichever bundle goes, :data:`ZERO_WIDTH_GUARD` follows it: viser's plot element draws once at width 0 when it
appears (before its size is measured), and plotly then falls back to 700 × 450 px; a figure whose margins need
more than 450 px (presenter mode and phones write their notes out above the plot) makes plotly throw "Something
went wrong with axis scaling", which takes viser's whole page down (docs/known-issues.rst). The guard skips a
draw at width 0; the element draws again once measured.
"""

from __future__ import annotations

import re
import threading
from collections.abc import Callable
from functools import lru_cache
from pathlib import Path
from typing import Any, cast

import plotly.graph_objects as go

from app.figures import registry
from app.figures.quantizer import channel_names
from app.figures.raw import Wire
from app.frames.render import Sent
from app.settings.values import is_nonlinear

from .viserfix import send_plotly_js

__all__ = ["ViewPanel", "blank_figure", "shared_blank", "PANEL_WIDTH", "VIEW_FIELDS"]
__all__ += ["BUNDLE", "TRACE_TYPES", "ZERO_WIDTH_GUARD", "bundle_version", "send_basic_bundle"]

# ----- plotly.js: the basic bundle ----------------------------------------------------------------------------
BUNDLE = Path(__file__).resolve().parent / "assets" / "plotly-basic.min.js"
#: The trace types the basic bundle draws.
TRACE_TYPES = ("scatter", "bar", "pie")
#: Run after plotly.js: ``Plotly.react`` with a layout 0 px wide draws nothing (see the module's docstring).
ZERO_WIDTH_GUARD = (
    "\n;(function(P){if(!P||P.__qsidGuard)return;var react=P.react;"
    "P.react=function(gd,data,layout,config){if(layout&&layout.width===0)return Promise.resolve(gd);"
    "return react.call(this,gd,data,layout,config);};P.__qsidGuard=true;})(window.Plotly);\n"
)


@lru_cache(maxsize=1)
def _bundle() -> tuple[str, str]:
    """(version, source) of the shipped basic bundle; ("", "") if it is missing."""
    try:
        text = BUNDLE.read_text(encoding="utf-8")
    except OSError:
        return "", ""
    return bundle_version(text), text


def bundle_version(source: str) -> str:
    """The version in a plotly.js bundle's banner ("plotly.js (basic - minified) v4.1.1" -> "4.1.1")."""
    m = re.search(r"plotly\.js[^\n]*?v(\d+\.\d+\.\d+)", source[:400])
    return m.group(1) if m else ""


def send_basic_bundle(gui: Any) -> str | None:
    """Queue the basic bundle to the tab of ``gui`` (a ``client.gui``) before its first plot.

    Returns None when it was sent, else why viser's own bundle will be sent instead.
    Call it before the tab's first ``add_plotly``.
    """
    import plotly.offline

    version, source = _bundle()
    wanted = plotly.offline.get_plotlyjs_version()
    note = None
    if version != wanted:  # the full bundle, as viser would send it, with the guard
        note = f"the shipped basic bundle is plotly.js {version or '(missing)'}, plotly needs {wanted}"
        source = plotly.offline.get_plotlyjs()
    if not send_plotly_js(gui, source + ZERO_WIDTH_GUARD):  # viser then skips sending its own bundle
        return "this viser version sends plotly.js differently (or it was sent already)"
    return note


# ----- the plots panel -----------------------------------------------------------------------------------------
#: The :class:`~app.settings.values.Values` fields set by the views' own inputs (not :data:`CONTROLS`).
VIEW_FIELDS = ("view_channel", "compare_bits")

#: Width of the plots panel (px): wide enough for the stacked time series and the side-by-side portraits.
PANEL_WIDTH = 640


def blank_figure() -> go.Figure:
    """The "computing …" placeholder of a plot not drawn yet."""
    fig = go.Figure()
    fig.update_layout(
        height=200,
        template="plotly_white",
        margin=dict(l=10, r=10, t=10, b=10),
        annotations=[dict(text="computing …", showarrow=False, x=0.5, y=0.5, xref="paper", yref="paper")],
        xaxis=dict(visible=False),
        yaxis=dict(visible=False),
    )
    return fig


@lru_cache(maxsize=1)
def shared_blank() -> go.Figure:
    """:func:`blank_figure` as every tab's plots are given it: built and made JSON once per process (a validated
    plotly figure with its template took ~20 ms, 17 per tab), through :class:`~app.frames.render.Sent` so its JSON
    carries the dashboard's plotly options (:data:`app.figures.raw.PLOT_CONFIG`). Never changed in place."""
    return cast(go.Figure, Sent(Wire(blank_figure()), 1.0))


class ViewPanel:
    """Groups of plots (``plots``: view name -> plotly handle) and the views' inputs, one group shown at a time.

    Parameters
    ----------
    gui : client.gui
    panel : the docked plots panel
    values, system : the tab's first settings
    on_change : callable()
        An input changed (marks the tab dirty).
    on_pin, on_unpin, on_datalength : callable()
        The Compare tab's buttons and the Data length tab's button.
    """

    def __init__(
        self,
        gui,
        panel,
        values,
        system,
        on_change: Callable[[], None],
        on_pin: Callable[[], None],
        on_unpin: Callable[[], None],
        on_datalength: Callable[[], None],
    ):
        self.plots: dict = {}
        self.system_names: tuple = ()
        #: None: plotly.js's basic bundle was sent (1.2 MB, not 4.8 MB); else why viser's full one goes
        self.plotly_js_note = send_basic_bundle(gui)
        #: the elements of each group (registry tab name -> handles), visible only while the group is chosen
        self.groups: dict[str, list] = {}
        self._show_lock = threading.RLock()
        self._shown = registry.TABS[0]
        with panel.add_tab("Plots"):  # one tab: viser draws it as the panel's plain header
            #: which group the panel shows (the person picks any; a lesson's is set by the server)
            self.group = gui.add_dropdown(
                "show",
                registry.TABS,
                initial_value=registry.TABS[0],
                hint="Which plots this panel shows (a lesson picks its own)",
            )
            for tab in registry.TABS + registry.KOOPMAN_TABS:
                self.groups[tab] = self._add_group(gui, tab, values, on_change, on_pin, on_unpin, on_datalength)
        self.group.on_update(lambda _e: self.show(str(self.group.value)))
        self.show(registry.TABS[0])
        self._orders: dict = {}
        self.set_system(system, int(values.view_channel))
        self.set_kind(is_nonlinear(values.system))

    def _add_group(self, gui, tab: str, values, on_change, on_pin, on_unpin, on_datalength) -> list:
        """The inputs and plots of group ``tab`` (built hidden; :meth:`show` reveals one group)."""
        out: list = []
        if tab == "Quantizer":
            self.channel = gui.add_dropdown(
                "channel",
                ("x",),
                hint="The signal quantized below: a state or an input of the training data (dither seed 0)",
                visible=False,
            )
            self.channel.on_update(lambda _e: on_change())
            out.append(self.channel)
        elif tab == "Data length":
            self.dl_button = gui.add_button(
                "Compute error vs data length",
                hint="10 lengths from 10³ to 10⁶ samples at the current b; any change cancels it",
                visible=False,
            )
            self.dl_button.on_click(lambda _e: on_datalength())
            self.dl_progress = gui.add_progress_bar(0.0, animated=False, visible=False)
            self.dl_status = gui.add_markdown(
                "Not computed yet (it takes ~10-60 s; other views stay live).", visible=False
            )
            out += [self.dl_button, self.dl_progress, self.dl_status]
        elif tab == "Compare":
            self.pin = gui.add_button(
                "Pin current result",
                hint="Keep the current curves: the error, cost and bound plots show them dashed until unpinned",
                visible=False,
            )
            self.unpin = gui.add_button("Unpin", disabled=True, visible=False)
            self.pin.on_click(lambda _e: on_pin())
            self.unpin.on_click(lambda _e: on_unpin())
            self.pin_note = gui.add_markdown("Nothing pinned.", visible=False)
            self.compare_bits = gui.add_text(
                "portraits at b",
                values.compare_bits,
                hint="Word lengths side by side, e.g. '2, 4, 6' (the letter's figures (d)-(f))",
                visible=False,
            )
            self.compare_bits.on_update(lambda _e: on_change())
            out += [self.pin, self.unpin, self.pin_note, self.compare_bits]
        for v in (v for v in registry.ALL_VIEWS if v.tab == tab):
            self.plots[v.name] = gui.add_plotly(shared_blank(), aspect=v.aspect, visible=False)
            out.append(self.plots[v.name])
        return out

    @property
    def shown(self) -> str:
        """The group the panel shows (one of :data:`app.figures.registry.TABS`)."""
        return self._shown

    def show(self, tab: str) -> None:
        """Show group ``tab`` and hide the others (from any thread: viser queues the changes in order)."""
        if tab not in self.groups:
            tab = registry.TABS[0]
        with self._show_lock:  # the dropdown's callback thread and the tab's worker (a lesson) both call this
            self._shown = tab
            if self.group.value != tab:
                self.group.value = tab  # its callback calls show again (same thread), which finds it done
            for name, handles in self.groups.items():
                for h in handles:
                    if h.visible != (name == tab):
                        h.visible = name == tab

    def open_lesson(self, plot: str, system, channel: int) -> None:
        """Show a lesson's key view: its group brought forward, the view first in it (above the fold), and the
        quantizer view on ``channel``."""
        tab = next(v.tab for v in registry.ALL_VIEWS if v.name == plot)
        if not self._orders:
            self._orders = {name: float(h.order) for name, h in self.plots.items()}
        same = [v.name for v in registry.ALL_VIEWS if v.tab == tab]
        for name, h in self.plots.items():  # the key view just above its group's first view, the others as built
            want = (min(self._orders[n] for n in same) - 0.5) if name == plot else self._orders[name]
            if h.order != want:
                h.order = want
        self.set_system(system)
        names = self.system_names
        self.channel.value = names[min(max(int(channel), 0), len(names) - 1)]
        self.set_kind(tab in registry.KOOPMAN_TABS)
        self.show(tab)

    def set_kind(self, nonlinear: bool) -> None:
        """Offer the groups of a nonlinear plant (:data:`~app.figures.registry.KOOPMAN_TABS`) or of a linear one;
        the group shown moves to the kind's first when it is not one of them."""
        tabs = registry.KOOPMAN_TABS if nonlinear else registry.TABS
        if tuple(self.group.options) != tabs:
            self.group.options = tabs
        if self._shown not in tabs:
            self.show(tabs[0])

    def set_system(self, system, channel: int | None = None) -> None:
        """Offer the channels of ``system`` (keeps the choice when the names did not change)."""
        names = channel_names(system)
        if names == self.system_names:
            return
        k = channel if channel is not None else 0
        self.system_names = names
        self.channel.options = names
        self.channel.value = names[min(max(k, 0), len(names) - 1)]

    def values(self) -> dict:
        """The :class:`~app.settings.values.Values` fields set here."""
        names = self.system_names
        ch = names.index(self.channel.value) if self.channel.value in names else 0
        return dict(view_channel=ch, compare_bits=str(self.compare_bits.value))

    def show_pinned(self, frame) -> None:
        if frame is None:
            self.pin_note.content = "Nothing pinned."
        else:
            v = frame.values
            self.pin_note.content = (
                f"Pinned (dashed): **{frame.system.name}**, b = {frame.bits}, {v.dither} dither, "
                f"{v.trajectories} × {v.steps} samples, {v.realizations} realizations, "
                f"input bound {v.u_max:g}"
            )
        self.unpin.disabled = frame is None
