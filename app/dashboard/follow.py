"""Follow links: one tab shown live and read-only in other tabs (a teacher's tab in a class's browsers).

A tab with a view of its own *leads* its code; a tab opened at that code's follow link (``/f/CODE``, see
:mod:`app.dashboard.viewcodes`) *follows* it (:class:`~app.dashboard.follower.Follower`). The leader computes
and draws as any tab does. After each draw it publishes what it drew to its code's :class:`Channel`
(:meth:`FollowHub.drawn`): the panel's values, the frame, and the 3-D scene, the summary and the figures it
pushed, each figure's JSON made once (:class:`Sent`) and shared by the leader's plot handles and every
follower's. Publishing costs the leader a few dictionary updates and one ``touch`` per follower (a
condition notified); it never waits for a follower.

Each follower's own worker thread, woken by that touch, pushes the items newer than those it pushed already
and sets its panel to the leader's values. Nothing is computed or rendered again, and followers take no
compute slot. Followers take their turns one at a time (:attr:`FollowHub.turn`), so however many follow,
at most one of them competes with the leader's worker for the interpreter; a follower whose turn comes late
pushes only the newest state (the items it missed are simply replaced).

When the leader's tab closes, its followers keep the last view and say so; a tab that opens the code again (a
reload of the teacher's tab) leads it again and the followers follow it from its next draw.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from .codepanel import count_followers, remember
from .follower import Follower, Snapshot
from .settings import Values
from .viewcodes import ViewStore

__all__ = ["FollowHub", "Channel", "Snapshot", "Sent", "Drawn"]


class Sent:
    """A figure as pushed to a plot handle, with the handle's height / width (``aspect``): its JSON made once (by
    the first handle given it), then reused by every follower's handle. viser's plot handle calls
    :meth:`to_json`; every other attribute is the figure's."""

    __slots__ = ("wire", "json", "aspect")

    def __init__(self, wire: Any, aspect: float):
        self.wire = wire  # an app.figures.raw.Wire (or a plotly figure)
        self.json: str | None = None
        self.aspect = aspect

    def to_json(self) -> str:
        if self.json is None:
            self.json = self.wire.to_json()
        return self.json

    def __getattr__(self, name: str) -> Any:
        return getattr(self.wire, name)


@dataclass
class Drawn:
    """What one draw pushed to a tab: the 3-D scene and the summary (None: unchanged) and the figures redrawn."""

    scene: Any = None
    summary: str | None = None
    figures: dict[str, Sent] = field(default_factory=dict)


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
