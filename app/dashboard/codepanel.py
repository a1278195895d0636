"""The view-code part of a tab's panel: its code and links, the "load view code" box and one status line.

A tab with a view of its own shows its code, its **link** (these settings in a tab of one's own; a reload of
the tab comes back to them too) and its **follow link** (this tab live and read-only, for a class; the number
of tabs following it is shown). A follower (:mod:`app.dashboard.follower`) shows the code it follows and that
follow link instead, and no load box. Which codes and links mean what: :mod:`app.dashboard.viewcodes`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from .settings import InputError, Values
from .viewcodes import ViewOpen, ViewStore, normalize_code, view_link

__all__ = ["CodePanel", "add_code_panel", "load_code", "remember", "show_view", "count_followers", "say"]


@dataclass
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
