"""A tab that follows another tab's view live and read-only, until the person explores from here.

:class:`Follower` is the follow state of one tab (:mod:`app.dashboard.follow` has the leader's side). Its
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
from dataclasses import dataclass
from typing import Any

from .codepanel import show_view
from .controls import CONTROLS, initial_value
from .lesson_mark import lesson_drift
from .lessons import get_lesson, lesson_markdown, lesson_names, lesson_values
from .render import Renderer
from .settings import Values, resolve_system
from .share import apply_values

__all__ = ["Follower", "Snapshot", "refused", "EXPLORE"]

#: The button that makes a follower a view of its own.
EXPLORE = "✎ explore from here"
#: The Values fields whose change rebuilds the weight sliders (the panel is set in full then).
_STRUCTURAL = ("system", "a_text", "b_text", "log_q", "log_r")


def refused(session: Any, handle: Any) -> str | None:
    """Why a value sent to input ``handle`` of ``session``'s panel is refused (None: it is not)."""
    follower = getattr(session, "follower", None)
    if follower is None or not follower.active or handle is None or follower.allows(handle):
        return None
    return (
        f"this tab follows view **{follower.code}** read-only: press **explore from here** to make it a view "
        "of your own, where every input works"
    )


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


@dataclass(frozen=True)
class Snapshot:
    """A follower's copy of the followed code's state (:meth:`app.dashboard.follow.FollowHub.snapshot`).

    ``leader``: the followed tab is open; ``items``: ``"scene"``, ``"summary"`` and each view's name ->
    (the publication that set it, the item)."""

    leader: bool
    values: Values | None
    frame: Any
    group: str | None
    items: dict[str, tuple[int, Any]]


class Follower:
    """The follow state of one tab (see the module docstring): built by
    :meth:`~app.dashboard.follow.FollowHub.attach` (``hub``)."""

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
        s.ui.renderer = Renderer()  # this tab draws its own frames from now on: every view anew
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
