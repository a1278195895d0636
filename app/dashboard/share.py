"""Keep and share a view, the panel's parts: the tab's view code and links with the "load view code" box, and
its "Save, load & export" folder (settings as a file, the command line, the exports).

A tab with a view of its own shows its code, its **link** (these settings in a tab of one's own; a reload of
the tab comes back to them too) and its **follow link** (this tab live and read-only, for a class; the number
of tabs following it is shown). A follower (:mod:`app.dashboard.follow`) shows the code it follows and that
follow link instead, and no load box. Which codes and links mean what: :mod:`app.settings.viewcodes`; settings
files: :mod:`app.settings.files`; the command line and exports: :mod:`app.frames.exports`.
:func:`add_share_panel` builds the folder from what it needs (the last frame, the panel's values, a way to send
a file and to hand loaded settings back) and :func:`show_frame` shows the command of a frame drawn.
"""

from __future__ import annotations

import dataclasses
import html
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from app.frames.exports import command_lines, curves_csv, curves_json, frame_html
from app.settings.files import settings_json, values_from_json
from app.settings.values import InputError, Values, resolve_system
from app.settings.viewcodes import ViewOpen, ViewStore, normalize_code, view_link

from .controls import CONTROLS, initial_value, set_system

if TYPE_CHECKING:
    from app.frames.frame import Frame

__all__ = [
    "apply_values",
    "mirror_panel",
    "add_share_panel",
    "show_frame",
    "ShareHandles",
    "CodePanel",
    "add_code_panel",
    "load_code",
    "remember",
    "show_view",
    "count_followers",
    "say",
]

_CONTROL = {c.name: c for c in CONTROLS}


# ----- the "Save, load & export" folder ------------------------------------------------------------------------
@dataclasses.dataclass
class ShareHandles:
    """The "Keep & share" folder of one tab: command text, status line, and a settings upload waiting."""

    command: Any  # viser markdown handles
    status: Any
    pending: Values | None = None
    shown: Values | None = None


def apply_values(el, v: Values) -> None:
    """Set every input of a tab's panel to ``v`` (from the tab's worker thread)."""
    system = resolve_system(v).system
    h = el.inputs
    for c in CONTROLS:
        if c.name != "axes":
            h[c.name].value = initial_value(c, v, system)
    el.system_key = None  # rebuild the weight sliders at the file's positions
    set_system(el, system, v.log_q, v.log_r, reset=False)
    axes = initial_value(_CONTROL["axes"], v, system)
    if axes in h["axes"].options:
        h["axes"].value = axes


#: The Values fields whose change rebuilds the weight sliders (the panel is set in full then).
_STRUCTURAL = ("system", "a_text", "b_text", "log_q", "log_r")


def mirror_panel(session: Any, old: Values | None, new: Values) -> None:
    """Set the panel of ``session`` from values ``old`` (what it shows; None: unknown) to ``new``."""
    el, views = session.controls, session.views
    if old is None or any(getattr(old, k) != getattr(new, k) for k in _STRUCTURAL):
        apply_values(el, new)
        views.set_system(resolve_system(new).system)
    else:  # the common case (b, a seed, a lesson): only the inputs that changed
        h = el.inputs
        changed = [c for c in CONTROLS if getattr(old, c.name) != getattr(new, c.name)]
        system = resolve_system(new).system if any(c.name in ("x0", "axes") for c in changed) else None
        for c in changed:
            want = initial_value(c, new, system) if system is not None else c.convert(getattr(new, c.name))
            if c.name != "axes" or want in h["axes"].options:
                h[c.name].value = want
    el.inputs["fixed_range"].visible = new.range_mode == "fixed"
    names = list(views.channel.options)
    views.channel.value = names[min(max(int(new.view_channel), 0), len(names) - 1)]
    views.compare_bits.value = new.compare_bits


def _download(
    sh: ShareHandles,
    frame: Frame | None,
    send: Callable[[str, bytes], None],
    name: str,
    make: Callable[[Frame | None], str],
    needs_frame: bool = True,
) -> None:
    """Send the file ``name`` made by ``make(frame)`` to the tab; the outcome in one line of ``sh.status``."""
    if needs_frame and frame is None:
        sh.status.content = "Nothing computed yet: wait for the first view."
        return
    try:
        text = make(frame)
    except Exception as exc:  # an export must never take the tab down
        sh.status.content = f"⚠️ Export failed ({type(exc).__name__}: {exc})"
        return
    send(name, text.encode("utf-8"))
    sh.status.content = f"Sent **{name}** ({len(text) / 1024:.0f} KiB)."


def _uploaded(sh: ShareHandles, receive: Callable[[Values], None], name: str, content: bytes) -> None:
    """A settings file arrived: checked, then handed to ``receive`` (or one line saying why not)."""
    try:
        v = values_from_json(content)
    except InputError as exc:
        sh.status.content = f"⚠️ **Cannot load {html.escape(name)}:** {exc}"
        return
    sh.status.content = f"Loaded settings from **{html.escape(name)}**."
    receive(v)


def add_share_panel(
    gui: Any,
    last_frame: Callable[[], Frame | None],
    panel_values: Callable[[], Values],
    send: Callable[[str, bytes], None],
    receive: Callable[[Values], None],
) -> ShareHandles:
    """The "Save, load & export" folder at the end of a tab's panel (built once per tab).

    Parameters
    ----------
    gui : viser.GuiApi
        The tab's GUI.
    last_frame : callable() -> Frame or None
        The frame the tab drew last (what the exports save).
    panel_values : callable() -> Values
        Everything set in the tab now (what "Download settings" saves).
    send : callable(name, data)
        Sends a file to the browser.
    receive : callable(Values)
        Settings loaded from a file (the tab applies them at its next run).
    """
    with gui.add_folder("Save, load & export", expand_by_default=False):
        down = gui.add_button("Download settings (JSON)", hint="Save every setting of this panel to a file")
        up = gui.add_upload_button(
            "Load settings (JSON)",
            mime_type="application/json",
            hint="Set the panel from a file saved with 'Download settings'",
        )
        gui.add_markdown("**As a command** (reproduces the numbers of the curves):")
        command = gui.add_markdown("")
        csv_b = gui.add_button("Export curves (CSV)")
        json_b = gui.add_button("Export curves (JSON)")
        html_b = gui.add_button("Export figures (HTML, offline)")
        status = gui.add_markdown("")
    sh = ShareHandles(command=command, status=status)

    def export(kind: str, make: Callable[[Frame | None], str]) -> None:
        frame = last_frame()
        _download(sh, frame, send, f"{frame.system.name if frame else 'qsid'}-{kind}", make)

    down.on_click(
        lambda _: _download(sh, None, send, "qsid-settings.json", lambda _f: settings_json(panel_values()), False)
    )
    csv_b.on_click(lambda _: export("curves.csv", curves_csv))
    json_b.on_click(lambda _: export("curves.json", curves_json))
    html_b.on_click(lambda _: export("figures.html", frame_html))
    up.on_upload(lambda e: _uploaded(sh, receive, e.target.value.name, e.target.value.content))
    return sh


def show_frame(sh: ShareHandles, frame: Frame) -> None:
    """After a frame is drawn: the command line for the settings it was computed with."""
    if frame.values == sh.shown:
        return
    sh.shown = frame.values
    try:
        lines = command_lines(frame.values)
    except Exception as exc:  # e.g. a setting without a flag: say so rather than show a wrong line
        sh.command.content = f"*(no command line: {exc})*"
        return
    sh.command.content = "\n".join(f"```\n{ln}\n```" for ln in lines)


# ----- the view code's lines and load box ---------------------------------------------------------------------
@dataclasses.dataclass
class CodePanel:
    """The tab's code line, the line under it, the "load view code" box and its status line (viser handles)."""

    view: ViewOpen
    line: Any
    hint: Any
    box: Any
    status: Any
    followers: int = 0


def _code_line(view: ViewOpen) -> str:
    if view.follow is not None:
        follow = view_link(view.host, view.follow, "f", view.short)
        return f"following view **{view.follow}** (read-only) · [follow link]({follow})"
    link, follow = view_link(view.host, view.code, "v", view.short), view_link(view.host, view.code, "f", view.short)
    shown = follow.removeprefix("http://") if view.short else "follow link"  # short enough to read off a screen
    return f"view code **{view.code}** · [link]({link}) · follow: [{shown}]({follow})"


def _hint_line(view: ViewOpen, followers: int) -> str:
    back = (
        "A reload or the link brings these settings back"
        if view.kept
        else "This tab's address does not hold its code: the link (or the code typed below) brings these settings back"
    )
    who = f" · **{followers} following**" if followers else ""
    return f"{back}; the follow link shows this tab live and read-only, e.g. to a class{who}."


def say(panel: CodePanel, text: str) -> None:
    """One line under the box ("" hides it)."""
    panel.status.content = text
    panel.status.visible = bool(text)


def show_view(panel: CodePanel, view: ViewOpen) -> None:
    """The panel for ``view`` (a follower that explored from here: its own code and links from now on)."""
    panel.view = view
    panel.line.content = _code_line(view)
    panel.hint.content = _hint_line(view, panel.followers)
    panel.hint.visible = panel.box.visible = view.follow is None


def count_followers(panel: CodePanel, n: int) -> None:
    """How many tabs follow this one (from any thread; the line under the code says it)."""
    if n != panel.followers:
        panel.followers = n
        panel.hint.content = _hint_line(panel.view, n)


def load_code(panel: CodePanel, store: ViewStore, text: str, receive: Callable[[Values], None]) -> None:
    """The "load view code" box: hand the settings of the code (or link) typed to ``receive``, or say in one
    line why not."""
    if not str(text or "").strip():  # the box emptied (by the tab after a load): the status line stays
        return
    try:
        code = normalize_code(text)
        v = store.get(code)
    except InputError as exc:
        say(panel, f"⚠️ {exc}")
        return
    if v is None:
        say(panel, f"⚠️ view code **{code}** is not known on this server (ask for the link or check the letters)")
        return
    say(panel, f"Loaded view **{code}** (this tab keeps its own code **{panel.view.code}**).")
    panel.box.value = ""  # emptied: the same code typed again is a change again, and loads again
    receive(v)


def add_code_panel(
    gui: Any, view: ViewOpen, after: Any, store: ViewStore, receive: Callable[[Values], None]
) -> CodePanel:
    """The code line and the load box, placed right after the panel element ``after`` (built once per tab).

    ``gui`` is the tab's ``viser.GuiApi``; a code typed in the box hands its settings to ``receive``.
    """
    order = float(after.order)
    line = gui.add_markdown("", order=order + 0.001)
    hint = gui.add_markdown("", order=order + 0.002)
    box = gui.add_text(
        "load view code",
        "",
        hint="Type a code (6 letters) or paste a view link: this tab takes that view's settings",
        order=order + 0.003,
    )
    status = gui.add_markdown("", visible=False, order=order + 0.004)
    panel = CodePanel(view, line, hint, box, status)
    show_view(panel, view)
    say(panel, view.note)
    box.on_update(lambda e: load_code(panel, store, e.target.value, receive))
    return panel


def remember(panel: CodePanel, store: ViewStore, values: Values) -> None:
    """After a frame is drawn: the tab's code keeps its newest settings (a follower keeps none)."""
    if panel.view.follow is None:
        store.put(panel.view.code, values)
