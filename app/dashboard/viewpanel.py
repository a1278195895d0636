"""The plots panel of a tab: one tab per :data:`app.figures.registry.TABS`, each with its views and their inputs.

The views' own inputs live next to the views: the quantizer's channel, the word
lengths of the side-by-side portraits, the pin buttons (Compare) and the
data-length study's button and progress (Data length). Like the left panel's
inputs, a change only marks the tab dirty; :meth:`ViewPanel.values` gives the
:class:`~app.dashboard.settings.Values` fields they set.
"""

from __future__ import annotations

import json
from collections.abc import Callable

import plotly.graph_objects as go

from app.figures import registry
from app.figures.quantizer import channel_names

from .plotlyjs import send_basic_bundle

__all__ = ["ViewPanel", "blank_figure", "show_tab_html", "PANEL_WIDTH", "VIEW_FIELDS"]

#: The :class:`~app.dashboard.settings.Values` fields set by the views' own inputs (not :data:`CONTROLS`).
VIEW_FIELDS = ("view_channel", "compare_bits")

#: Width of the plots panel (px): wide enough for the stacked time series and the side-by-side portraits.
PANEL_WIDTH = 640


def blank_figure() -> go.Figure:
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


def show_tab_html(tab: str, nonce: int) -> str:
    """HTML whose image fails to load at once (an empty data URL) and so runs a script that presses Enter on
    the plots panel's tab ``tab`` (the tab strip that also holds "Identification"), the keyboard way the
    dock activates a tab. ``nonce`` makes each call new content, so the browser runs it again."""
    first = json.dumps(registry.TABS[0])
    script = (
        "var t=[].slice.call(document.querySelectorAll('[role=tab]'));"
        f"var s=t.filter(function(e){{return e.title=={first};}}).map(function(e){{return e.parentElement;}})[0];"
        f"var g=s&&[].slice.call(s.querySelectorAll('[role=tab]')).filter(function(e){{return e.title=={json.dumps(tab)};}})[0];"
        "if(g){g.dispatchEvent(new KeyboardEvent('keydown',{key:'Enter',bubbles:true}));}"
    )
    return (
        f'<img alt="" data-qsid-tab="{nonce}" src="data:," style="display:none" '
        f'onerror="{script.replace(chr(34), "&quot;")}">'
    )


class ViewPanel:
    """Tabs of plots (``plots``: view name -> plotly handle) and the views' inputs.

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
        for tab in registry.TABS:
            with panel.add_tab(tab):
                if tab == "Quantizer":
                    self.channel = gui.add_dropdown(
                        "channel",
                        ("x",),
                        hint="The signal quantized below: a state or an input of the training data (dither seed 0)",
                    )
                    self.channel.on_update(lambda _e: on_change())
                elif tab == "Data length":
                    self.dl_button = gui.add_button(
                        "Compute error vs data length",
                        hint="10 lengths from 10³ to 10⁶ samples at the current b; any change cancels it",
                    )
                    self.dl_button.on_click(lambda _e: on_datalength())
                    self.dl_progress = gui.add_progress_bar(0.0, animated=False)
                    self.dl_status = gui.add_markdown("Not computed yet (it takes ~10-60 s; other views stay live).")
                elif tab == "Compare":
                    self.pin = gui.add_button(
                        "Pin current result",
                        hint="Keep the current curves: the error, cost and bound plots show them dashed until unpinned",
                    )
                    self.unpin = gui.add_button("Unpin", disabled=True)
                    self.pin.on_click(lambda _e: on_pin())
                    self.unpin.on_click(lambda _e: on_unpin())
                    self.pin_note = gui.add_markdown("Nothing pinned.")
                    self.compare_bits = gui.add_text(
                        "portraits at b",
                        values.compare_bits,
                        hint="Word lengths side by side, e.g. '2, 4, 6' (the letter's figures (d)-(f))",
                    )
                    self.compare_bits.on_update(lambda _e: on_change())
                for v in (v for v in registry.VIEWS if v.tab == tab):
                    self.plots[v.name] = gui.add_plotly(blank_figure(), aspect=v.aspect)
        #: runs the one-line script of :func:`show_tab_html` (viser has no server call that activates a tab)
        self.tab_switch = gui.add_html("", visible=False)
        self._switches = 0
        self._orders: dict = {}
        self.set_system(system, int(values.view_channel))

    def open_lesson(self, plot: str, system, channel: int) -> None:
        """Show a lesson's key view: its tab brought forward, the view first in it (above the fold), and the
        quantizer view on ``channel``."""
        tab = next(v.tab for v in registry.VIEWS if v.name == plot)
        if not self._orders:
            self._orders = {name: float(h.order) for name, h in self.plots.items()}
        same = [v.name for v in registry.VIEWS if v.tab == tab]
        for name, h in self.plots.items():  # the key view just above its tab's first view, the others as built
            want = (min(self._orders[n] for n in same) - 0.5) if name == plot else self._orders[name]
            if h.order != want:
                h.order = want
        self.set_system(system)
        names = self.system_names
        self.channel.value = names[min(max(int(channel), 0), len(names) - 1)]
        self._switches += 1
        self.tab_switch.content = show_tab_html(tab, self._switches)
        self.tab_switch.visible = True

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
        """The :class:`~app.dashboard.settings.Values` fields set here."""
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
