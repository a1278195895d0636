"""The viser side of one browser tab: its panels, and what it shows of a computation (frames, progress, errors).

:class:`TabView` builds the left panel, the plots panel, the 3-D scene and the "Save, load & export" and view-code
parts once, and then only draws: :meth:`TabView.draw` pushes a :class:`~app.frames.frame.Frame`,
:meth:`TabView.show_error` and :meth:`TabView.show_progress` the state of a computation, :meth:`TabView.refuse`
a value sent that an input did not take. It owns no thread and
computes nothing: the frames come from :func:`app.frames.compute.iter_frames` (a pure function from the
settings to the frames), driven by the tab's worker (:class:`app.dashboard.session.Session`).
"""

from __future__ import annotations

import threading
import warnings
from collections.abc import Callable
from typing import Any

from app.frames.frame import Frame
from app.frames.render import Drawn, Figures, Renderer
from app.settings.values import Values, resolve_system
from app.settings.viewcodes import ViewOpen, ViewStore
from qsid_core import PRESETS, get_system

from .controls import GuiElements, make_gui_elements, read_values
from .phone import PHONE_SHEET_CSS, PhoneLayout, canvas_aspect
from .presenter import AutoPlay, PresenterLayout
from .scene import PhasePortrait
from .share import CodePanel, ShareHandles, add_code_panel, add_share_panel, apply_values
from .viewpanel import PANEL_WIDTH, ViewPanel

__all__ = ["TabView", "drop_late_draws", "CLOSED_CONNECTION"]

#: viser's warning for a message pushed to a tab whose connection is closed (see :func:`drop_late_draws`)
CLOSED_CONNECTION = r"Queued a \w+ on a closed connection"


def drop_late_draws() -> None:
    """Drop, quietly and by design, what a tab's worker pushes after its browser tab closed.

    A tab's worker checks that its tab is open before each draw, but the tab can close between that check
    and the draw's last message (viser closes the connection before it calls ``on_client_disconnect``, so
    no lock of ours can order the two). viser discards such messages (they would never be delivered) and
    warns once per connection; for the dashboard that is the expected end of a draw, not a leak: the
    worker stops at its next check and the tab's handles are released with it. Only that warning is
    ignored (a ``warnings`` filter on its text).
    """
    warnings.filterwarnings("ignore", message=CLOSED_CONNECTION, category=UserWarning)


class TabView:
    """The panels of one tab (viser handles) and how a frame, a progress or an error is shown in them.

    Parameters
    ----------
    client : viser.ClientHandle
    values : Values
        The tab's first settings.
    touch : callable(user=False)
        Marks the tab dirty (every input's callback calls it).
    view : ViewOpen, optional
        The tab's view code (None: no code line).
    store : ViewStore, optional
        Where view codes are kept (needed with ``view``).
    figures : Figures, optional
        The server's figures, made once for every tab that draws the same (None: this tab makes its own).
    last_frame : callable() -> Frame or None
        The frame drawn last (for the exports).
    on_pin, on_unpin, on_datalength : callable()
        The Compare group's buttons and the Data length group's button.
    """

    def __init__(
        self,
        client: Any,
        values: Values,
        touch: Callable[..., None],
        view: ViewOpen | None,
        store: ViewStore | None,
        last_frame: Callable[[], Frame | None],
        on_pin: Callable[[], None],
        on_unpin: Callable[[], None],
        on_datalength: Callable[[], None],
        figures: Figures | None = None,
    ):
        self.client = client
        self.touch = touch
        # the canvas's shape before this tab docks a panel of its own (read later, it depends on which of them
        # the browser had laid out when it last sent the camera): the window's shape, less viser's panel
        connect_aspect = canvas_aspect(client.camera)
        #: settings that arrived from a file or a view code; the worker applies them at its next run
        self.pending: Values | None = None
        gui = client.gui
        gui.configure_theme(show_share_button=False, control_width="large", show_logo=False)
        # place the panels before filling them: moving a filled panel re-mounts its plots
        gui.main_panel.dock_left()
        self.plots_panel = gui.add_panel()
        self.plots_panel.dock_right()
        self.plots_panel.set_width(PANEL_WIDTH)
        system = get_system(values.system) if values.system in PRESETS else resolve_system(values).system
        self.controls: GuiElements = make_gui_elements(gui, values, system, touch)
        self.play = AutoPlay(self.controls.play, self.controls["bits"], touch)
        self.controls.play.on_click(lambda _e: self.play.press())
        self.codes: CodePanel | None = None
        if view is not None and store is not None:
            self.codes = add_code_panel(gui, view, self.controls.play, store, self.receive)
        self.share: ShareHandles = add_share_panel(
            gui, last_frame, self.panel_values, self._send_file, self.receive
        )  # keep & share: settings file, command line, exports
        self.views = ViewPanel(gui, self.plots_panel, values, system, touch, on_pin, on_unpin, on_datalength)
        self.plots = self.views.plots
        self.renderer = Renderer(figures)  # (a linear and a nonlinear plant's frames alike)
        self.portrait = PhasePortrait(client.scene, camera=client.camera)
        self.presenter = PresenterLayout(gui, self.plots_panel, self.portrait, PANEL_WIDTH, self.controls.play, touch)
        self.phone = PhoneLayout(
            gui, client.camera, self.controls, self.plots_panel, self.portrait, touch, aspect=connect_aspect
        )
        gui.add_html(PHONE_SHEET_CSS, order=1e9)  # phone sheet: window-wide, at most half as high (nothing drawn)
        #: why the computation of the settings shown could not run (None: it could), and the values sent for an
        #: input that were refused (by the input: each stays shown until that input is changed again)
        self.run_error: str | None = None
        self.refusals: dict[int, str] = {}
        self.last_error: str | None = None
        self._errors = threading.RLock()  # refusals come from viser's event loop, the rest from the tab's worker
        #: what the last draw pushed (a leader's followers push the same: :mod:`app.dashboard.follow`)
        self.drawn = Drawn()

    # ----- settings in and out ----------------------------------------------------------------------------------
    def panel_values(self) -> Values:
        """Everything set in the tab: the controls and the plots panel's own fields (channel, compared b)."""
        return read_values(self.controls).replace(**self.views.values())

    def receive(self, values: Values) -> None:
        """Settings loaded from a file or a view code: applied by the worker at its next run."""
        self.pending = values
        self.touch()

    def apply_pending(self) -> Values | None:
        """(worker) Set the panel to settings received since the last run; returns them (None: none arrived)."""
        v, self.pending = self.pending, None
        if v is None:
            return None
        self.clear_errors()  # every input set anew
        apply_values(self.controls, v)
        self.views.set_system(resolve_system(v).system)
        names = list(self.views.channel.options)
        self.views.channel.value = names[min(max(int(v.view_channel), 0), len(names) - 1)]
        self.views.compare_bits.value = v.compare_bits
        return v

    def _send_file(self, name: str, data: bytes) -> None:
        # save_immediately: one click saves the file (otherwise viser shows a link to click a second time)
        self.client.send_file_download(name, data, save_immediately=True)

    # ----- what the tab shows -------------------------------------------------------------------------------------
    def show_error(self, text: str) -> None:
        """One line under the panel's inputs: the settings cannot be computed; the views keep the last good
        result (until a computation draws again)."""
        with self._errors:
            self.run_error = text
            self._show_errors(text)

    def refuse(self, handle: Any, text: str) -> None:
        """A value sent for input ``handle`` was refused (the input keeps, and shows, the value in use): one line
        that stays until that input is changed again (:meth:`accept`), whatever is drawn meanwhile."""
        with self._errors:
            self.refusals.pop(id(handle), None)
            self.refusals[id(handle)] = text  # (the newest last)
            self._show_errors(text)

    def accept(self, handle: Any) -> None:
        """A value sent for input ``handle`` was taken: its refusal line goes."""
        with self._errors:
            if self.refusals.pop(id(handle), None) is not None:
                self._show_errors(None)

    def forget(self, handles: Any) -> None:
        """Inputs removed from the panel (the weight sliders of a previous system): their refusals go."""
        with self._errors:
            if any(self.refusals.pop(id(h), None) is not None for h in list(handles)):
                self._show_errors(None)

    def clear_errors(self) -> None:
        """No error line any more (the panel was set anew: settings loaded, another system, a view followed)."""
        with self._errors:
            self.run_error = None
            self.refusals.clear()
            self._show_errors(None)

    def _show_errors(self, newest: str | None) -> None:
        """The error box: every refusal, then why the settings cannot be computed; hidden when there is none.
        ``newest``: the line just added (the status line then says "error")."""
        c = self.controls
        if newest is not None:
            c.status.content = "error – see below"  # first: once the error shows, the status says so too
            c.progress.value = 0.0
        lines = [f"⚠️ **Refused:** {t}" for t in self.refusals.values()]
        if self.run_error is not None:
            lines.append(f"⚠️ **Cannot update:** {self.run_error}  \n*The view still shows the last good result.*")
        self.last_error = (
            newest if newest is not None else (self.run_error or next(reversed(self.refusals.values()), None))
        )
        if lines:
            c.error.content = "  \n".join(lines)
        if c.error.visible != bool(lines):
            c.error.visible = bool(lines)

    def show_progress(self, fraction: float, text: str) -> None:
        self.controls.progress.value = 100.0 * fraction
        self.controls.status.content = text

    def draw(self, frame: Frame, stale: Callable[[], bool]) -> bool:
        """Push ``frame`` unless ``stale()`` (newer settings arrived) before it is sent; True if drawn."""
        c = self.controls
        if stale():
            return False
        r = self.renderer.render(frame, c["axes"].value, self.phone.narrow)
        if stale():  # never draw an older result over a newer one
            self.renderer.reset()  # it remembered figures that were not pushed
            return False
        figures = r.figures  # each one's JSON made once, for every tab drawing it and every follower
        with self.client.atomic():
            with self._errors:
                if self.run_error is not None or (c.error.visible and not self.refusals):
                    self.run_error = None
                    self._show_errors(None)  # a refusal stays: the input shows the value these results are for
            if r.scene is not None:
                self.portrait.draw(r.scene)
            if r.summary is not None:
                c.summary.content = r.summary
            for name, fig in figures.items():
                h = self.plots[name]
                if h.aspect != fig.aspect:  # presenter mode and phones: as high as the figure's layout
                    h.aspect = fig.aspect
                h.figure = fig
        self.drawn = Drawn(r.scene, r.summary, figures)
        return True
