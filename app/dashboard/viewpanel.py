"""The plots panel of a tab: one group per :data:`app.figures.registry.TABS`, each with its views and their inputs.

The panel shows one group at a time, chosen in its "show" dropdown. The server owns that choice: a lesson
brings its group forward by setting the dropdown (:meth:`ViewPanel.show`), which hides the other groups'
elements through viser's public ``visible`` property. (viser has no server call that activates one of a
panel's client-side tabs, so the groups are not panel tabs; nothing is run in the page to press one.)

The views' own inputs live next to the views: the quantizer's channel, the word
lengths of the side-by-side portraits, the pin buttons (Compare) and the
data-length study's button and progress (Data length). Like the left panel's
inputs, a change only marks the tab dirty; :meth:`ViewPanel.values` gives the
:class:`~app.dashboard.settings.Values` fields they set.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import cast

import plotly.graph_objects as go

from app.figures import registry
from app.figures.quantizer import channel_names
from app.figures.raw import Wire

from .koopman_settings import is_nonlinear
from .plotlyjs import send_basic_bundle

__all__ = ["ViewPanel", "blank_figure", "PANEL_WIDTH", "VIEW_FIELDS"]

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
            # (through Wire: its JSON carries the dashboard's plotly options, app.figures.raw.PLOT_CONFIG)
            blank = cast(go.Figure, Wire(blank_figure()))
            self.plots[v.name] = gui.add_plotly(blank, aspect=v.aspect, visible=False)
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
