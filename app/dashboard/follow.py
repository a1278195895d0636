"""Follow links: one tab shown live and read-only in other tabs (a teacher's tab in a class's browsers).

A tab with a view of its own *leads* its code; a tab opened at that code's follow link (``/f/CODE``, see
:mod:`app.settings.viewcodes`) *follows* it (:class:`Follower`). The leader computes and draws as any tab does.
After each draw it publishes what it drew to its code's :class:`Channel` (:meth:`FollowHub.drawn`): the panel's
values, the frame, and the 3-D scene, the summary and the figures it pushed, each figure's JSON made once
(:class:`~app.frames.render.Sent`) and shared by the leader's plot handles and every follower's. Publishing
costs the leader a few dictionary updates and one ``touch`` per follower; it never waits for a follower.

Each follower's own worker thread, woken by that touch, pushes the items newer than those it pushed already
and sets its panel to the leader's values. Nothing is computed or rendered again, and followers take no
compute slot. Followers take their turns one at a time (:attr:`FollowHub.turn`), so however many follow,
at most one of them competes with the leader's worker for the interpreter; a follower whose turn comes late
pushes only the newest state (the items it missed are simply replaced).

When the leader's tab closes, its followers keep the last view and say so; a tab that opens the code again (a
reload of the teacher's tab) leads it again and the followers follow it from its next draw.

A follower follows until the person explores from here. :class:`Follower` is the follow state of one tab (:class:`FollowHub` has the leader's side). Its
:meth:`~Follower.mirror` runs on the tab's own worker thread (the only thread that draws into the tab): it sets
the panel to the leader's newest values and pushes the scene, summary and figures the leader drew, only
those newer than what this tab shows. Every input of the panel is disabled while following, and a value
sent anyway is refused with one line (:func:`refused`); the plots panel's "show" dropdown and presenter
mode's scene/plot switch stay usable (they only choose what this screen shows). **explore from here** turns
the tab into a view of its own: the code its address names as spare (or a new one), the followed view's
settings at that moment, every input enabled; nothing done there reaches the followed tab.
"""

from __future__ import annotations

import dataclasses
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from app.frames.render import Drawn
from app.lessons.drift import lesson_drift, lesson_markdown
from app.lessons.table import get_lesson, lesson_names, lesson_values
from app.settings.values import Values, resolve_system
from app.settings.viewcodes import ViewStore

from .share import count_followers, mirror_panel, remember, show_view

__all__ = ["FollowHub", "Channel", "Snapshot", "Follower", "refused", "EXPLORE"]


#: The button that makes a follower a view of its own.
EXPLORE = "✎ explore from here"


def refused(session: Any, handle: Any) -> str | None:
    """Why a value sent to input ``handle`` of ``session``'s panel is refused (None: it is not)."""
    follower = getattr(session, "follower", None)
    if follower is None or not follower.active or handle is None or follower.allows(handle):
        return None
    return (
        f"this tab follows view **{follower.code}** read-only: press **explore from here** to make it a view "
        "of your own, where every input works"
    )


@dataclass(frozen=True)
class Snapshot:
    """A follower's copy of the followed code's state (:meth:`FollowHub.snapshot`).

    ``leader``: the followed tab is open; ``items``: ``"scene"``, ``"summary"`` and each view's name ->
    (the publication that set it, the item)."""

    leader: bool
    values: Values | None
    frame: Any
    group: str | None
    items: dict[str, tuple[int, Any]]


class Follower:
    """The follow state of one tab (see the module docstring): built by
    :meth:`FollowHub.attach` (``hub``)."""

    def __init__(self, hub: Any, session: Any, code: str):
        self.hub, self.session, self.code = hub, session, code
        self.active = True
        self.seen: dict[str, int] = {}  # item -> the publication this tab pushed
        self.values: Values | None = None  # the values the panel was set to
        self.group: str | None = None
        self.state = ""  # what the banner says: "open", "left", "waiting", "explored"
        self._explore = False
        # at the top of the panel, above the lesson (on a phone the panel opens there)
        gui, order = session.client.gui, float(session.controls["lesson"].order)
        self.banner = gui.add_markdown("", order=order - 0.2)
        self.button = gui.add_button(
            EXPLORE,
            hint="Make this tab a view of your own, from these settings: every input works, nothing reaches the "
            "followed tab",
            order=order - 0.1,
        )
        self.button.on_click(lambda _e: self.want_explore())
        self.lock()

    def touch(self) -> None:
        """Something was published (or the leader came or went): the tab's worker mirrors it."""
        self.session.touch()

    def want_explore(self) -> None:
        """The button: the tab's worker makes it a view of its own at its next run."""
        self._explore = True
        self.session.touch(user=True)

    def allows(self, handle: Any) -> bool:
        """Inputs a follower may use: explore, and the choice of what this screen shows."""
        s = self.session
        return any(handle is h for h in (self.button, s.views.group, s.presenter.switch))

    def _inputs(self) -> list:
        s = self.session
        c, v = s.controls, s.views
        return [
            *c.inputs.values(),
            *c.q_sliders,
            *c.r_sliders,
            c.play,
            s.mark.back,
            s.codes.box,
            *(v.channel, v.compare_bits, v.pin, v.unpin, v.dl_button),
        ]

    def lock(self) -> None:
        """Every input disabled (again: rebuilt weight sliders come enabled)."""
        for h in self._inputs():
            if not h.disabled:
                h.disabled = True

    def _unlock(self) -> None:
        s = self.session
        for h in self._inputs():
            h.disabled = False
        h = s.controls.inputs
        h["a_text"].disabled = h["b_text"].disabled = h["system"].value != "custom"
        h["rho"].disabled = bool(h["rho_auto"].value)
        s.views.unpin.disabled = s.pinned is None

    # ----- the tab's worker ---------------------------------------------------------------------------------------
    def mirror(self) -> bool:
        """Show the followed view's newest state; False when the tab must compute (nothing published yet, or
        the person explored from here: the tab is then a view of its own)."""
        if not self.active:
            return False
        if self._explore:
            self._explore_now()
            return False
        with self.hub.turn:  # one follower at a time
            snap = self.hub.snapshot(self.code)
            self._say(("open" if snap.leader else "left") if snap.values is not None else "waiting")
            if snap.values is None:  # the view's saved settings, computed here (read-only) until its tab draws
                return False
            with self.session.client.atomic():  # one wake-up of the event loop for all of it
                self._show(snap)
                self.lock()
        return True

    def _show(self, snap: Snapshot) -> None:
        s, v = self.session, snap.values
        assert v is not None
        c = s.controls
        moved = v != self.values
        if moved:
            if (self.values is None or v.lesson != self.values.lesson) and v.lesson in lesson_names()[1:]:
                lv = lesson_values(v.lesson)  # the lesson's key view brought forward, as in the followed tab
                s.views.open_lesson(get_lesson(v.lesson).plot, resolve_system(lv).system, lv.view_channel)
            mirror_panel(s, self.values, v)
            s.lesson_shown = v.lesson
            drift = lesson_drift(v.lesson, v)
            c.lesson_text.content = lesson_markdown(v.lesson, drift)
            c.lesson_text.visible = bool(c.lesson_text.content)
            s.mark.drift, s.mark.back.visible = drift, bool(drift)
            self.values = v
        # (every run: the presenter switch is this screen's own choice, applied here as in any tab)
        s.presenter.apply(bool(v.presenter), narrow=s.ui.phone.narrow)
        if snap.group is not None and snap.group != self.group:
            s.views.show(snap.group)
            self.group = snap.group
        new = {key: item for key, item in snap.items.items() if self.seen.get(key) != item[0]}
        for key, (seq, item) in new.items():
            if key == "scene":
                s.portrait.draw(item)
            elif key == "summary":
                c.summary.content = item
            elif key in s.plots:
                h = s.plots[key]
                if h.aspect != item.aspect:
                    h.aspect = item.aspect
                h.figure = item
            self.seen[key] = seq
        if new and c.error.visible:  # a refused input's line: the followed view moved on
            s.ui.clear_errors()
        f = snap.frame
        status = f"{'ready' if f.complete else 'computing …'} · b = {f.bits} drawn (view {self.code})"
        if status != c.status.content:
            c.status.content = status
            c.progress.value = 100.0 if f.complete else c.progress.value
        s.last_frame = f  # (the exports save it)
        s.frames_drawn += bool(moved or new)

    def _say(self, state: str) -> None:
        if state == self.state:
            return
        self.state = state
        code = self.code
        text = {
            "open": f"**Following view {code} live.** Its settings and plots appear here as they change; "
            "this panel cannot change them.",
            "left": f"⚠️ **The tab of view {code} has closed.** This tab keeps its last view, and follows again "
            "if that view opens again.",
            "waiting": f"**Following view {code}.** Its tab is not open: this tab shows that view's saved "
            "settings, and follows it live once it opens.",
        }[state]
        self.banner.content = text + " *Explore from here* makes this tab a view of your own."

    def _explore_now(self) -> None:
        """Make the tab a view of its own (see the module docstring); its worker then computes it."""
        s, hub = self.session, self.hub
        self._explore, self.active = False, False
        hub.leave(self.code, self)
        view = s.codes.view
        own, kept = view.code, view.kept
        if own in hub.store or hub.in_use(own, s):  # (another tab took it meanwhile)
            own, kept = hub.store.new_code(), False
        hub.store.put(own, s.ui.panel_values())
        show_view(s.codes, dataclasses.replace(view, code=own, follow=None, kept=kept, note=""))
        self._unlock()
        s.ui.renderer.reset()  # this tab draws its own frames from now on: every view anew
        s.lesson_shown = str(s.controls["lesson"].value)
        self.state = "explored"
        back = (
            "A reload keeps it."
            if kept
            else f"The address bar still holds the follow link (a reload follows view {self.code} again): "
            "come back to this view with its link above."
        )
        self.banner.content = (
            f"✎ **This tab is now your own view {own}**, from view {self.code}'s settings at that moment: "
            f"changes here stay here. {back}"
        )
        self.button.visible = False
        hub.lead(own, s)


@dataclass
class Channel:
    """The state of one code as its followers see it: the leader (None: its tab is not open), the followers,
    and the newest published state; ``items`` maps ``"scene"``, ``"summary"`` and each view's name to
    (the publication that set it, the item)."""

    leader: Any = None
    followers: set = field(default_factory=set)
    seq: int = 0
    values: Values | None = None
    frame: Any = None
    group: str | None = None
    items: dict[str, tuple[int, Any]] = field(default_factory=dict)


class FollowHub:
    """Every code's channel (one hub per server; thread-safe).

    Parameters
    ----------
    store : ViewStore
        The view codes (a leader's settings are kept there after each draw).
    in_use : callable(code, but) -> bool
        True while an open tab other than session ``but`` has ``code`` as its own (a follower exploring takes
        another code then).
    """

    def __init__(self, store: ViewStore, in_use: Callable[[str, Any], bool]):
        self.store = store
        self.in_use = in_use
        self._lock = threading.Lock()
        self._channels: dict[str, Channel] = {}
        #: held by a follower while it pushes: followers push one at a time
        self.turn = threading.Lock()

    # ----- tabs joining and leaving (viser's connect/disconnect threads; a follower's worker on explore) -----------
    def attach(self, session: Any) -> Follower | None:
        """A new tab: the leader of its own code, or a follower (returned) of the code it follows."""
        codes = session.codes
        if codes is None:
            return None
        session.views.group.on_update(lambda _e: self.regroup(session))
        if codes.view.follow is None:
            self.lead(codes.view.code, session)
            return None
        follower = Follower(self, session, codes.view.follow)
        with self._lock:
            ch = self._channels.setdefault(follower.code, Channel())
            ch.followers.add(follower)
            leader, n = ch.leader, len(ch.followers)
        if leader is not None:
            count_followers(leader.codes, n)
        return follower

    def lead(self, code: str, session: Any) -> None:
        """``session`` shows ``code`` as its own: its followers follow it from its next draw."""
        with self._lock:
            ch = self._channels.setdefault(code, Channel())
            ch.leader = session
            followers = list(ch.followers)
        count_followers(session.codes, len(followers))
        self._wake(followers)

    def leave(self, code: str, follower: Follower) -> None:
        """``follower`` no longer follows ``code`` (its tab closed, or it explored from here)."""
        with self._lock:
            ch = self._channels.get(code)
            if ch is None:
                return
            ch.followers.discard(follower)
            leader, n = ch.leader, len(ch.followers)
            if leader is None and not n:
                del self._channels[code]
        if leader is not None:
            count_followers(leader.codes, n)

    def detach(self, session: Any) -> None:
        """The tab of ``session`` closed: a follower leaves; a leader's followers keep the last view."""
        follower = getattr(session, "follower", None)
        if follower is not None and follower.active:
            self.leave(follower.code, follower)
            return
        codes = getattr(session, "codes", None)
        if codes is None:
            return
        with self._lock:
            ch = self._channels.get(codes.view.code)
            if ch is None or ch.leader is not session:
                return
            ch.leader = None
            followers = list(ch.followers)
            if not followers:
                del self._channels[codes.view.code]
        self._wake(followers)

    # ----- the leader publishing (its worker thread; the plots panel's dropdown) ----------------------------------------
    def drawn(self, session: Any, frame: Any) -> None:
        """After ``session`` drew ``frame``: its code keeps the settings, its followers get what it drew."""
        codes = session.codes
        follower = getattr(session, "follower", None)
        if codes is None:
            return
        if follower is not None and follower.active:  # a follower drawing its own computation (nothing to follow yet)
            follower.lock()
            return
        values = session.ui.panel_values()
        remember(codes, self.store, values)
        drawn: Drawn = session.ui.drawn
        with self._lock:
            ch = self._channels.get(codes.view.code)
            if ch is None or ch.leader is not session:
                return
            ch.seq += 1
            ch.values, ch.frame, ch.group = values, frame, session.views.shown
            if drawn.scene is not None:
                ch.items["scene"] = (ch.seq, drawn.scene)
            if drawn.summary is not None:
                ch.items["summary"] = (ch.seq, drawn.summary)
            for name, fig in drawn.figures.items():
                ch.items[name] = (ch.seq, fig)
            followers = list(ch.followers)
        self._wake(followers)

    def regroup(self, session: Any) -> None:
        """The leader's plots panel shows another group: so do its followers."""
        codes = session.codes
        with self._lock:
            ch = self._channels.get(codes.view.code)
            if ch is None or ch.leader is not session or ch.group == session.views.shown:
                return
            ch.group = session.views.shown
            followers = list(ch.followers)
        self._wake(followers)

    def snapshot(self, code: str) -> Snapshot:
        """The state of ``code`` for a follower (a shallow copy: the items themselves are never changed)."""
        with self._lock:
            ch = self._channels.get(code) or Channel()
            return Snapshot(ch.leader is not None, ch.values, ch.frame, ch.group, dict(ch.items))

    def followers(self, code: str) -> int:
        """How many tabs follow ``code`` now."""
        with self._lock:
            ch = self._channels.get(code)
            return len(ch.followers) if ch is not None else 0

    @staticmethod
    def _wake(followers: list) -> None:
        for f in followers:
            f.touch()
