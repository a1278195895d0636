"""Views that survive a reload and travel: a short code per tab whose settings the server keeps.

Every tab has a view code (six letters). Its settings are kept on the server (:class:`ViewStore`: in memory and
in a small JSON file under the user's cache directory, at most :data:`MAX_VIEWS` codes, the least recently used
dropped first) and updated each time the tab draws new settings. The link

    ``http://HOST:PORT/?websocket=ws://HOST:PORT/v/CODE``

opens a tab on that code: viser's client connects its websocket to the address in ``?websocket=`` (path
included) and keeps the parameter in the address bar, so a reload connects to the same path again; the server
reads the path of the websocket request (:func:`app.dashboard.viserfix.connection_request`) and applies the
code's settings. A tab opened without a code gets a new one, and its address bar is rewritten to its link
(``history.replaceState``), so a reload of that tab comes back with its settings too. A code typed into the
panel's "load view code" box applies that code's settings to the tab.
"""

from __future__ import annotations

import html
import json
import os
import re
import secrets
import threading
import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .settings import InputError, Values
from .share import settings_json, values_from_json

__all__ = [
    "ViewStore",
    "MAX_VIEWS",
    "CODE_LETTERS",
    "new_code",
    "normalize_code",
    "code_from_path",
    "view_link",
    "default_store_path",
    "ViewOpen",
    "open_view",
    "CodePanel",
    "add_code_panel",
    "load_code",
    "remember",
]

#: Letters of a code: lower case without i, l, o (not to be confused with 1 and 0 when read off a projector).
CODE_LETTERS = "abcdefghjkmnpqrstuvwxyz"
CODE_LENGTH = 6
#: Codes kept (memory and file); the least recently used beyond that are dropped.
MAX_VIEWS = 1000
#: Seconds between two writes of the file (the newest settings are written at the latest on close).
WRITE_EVERY = 2.0
_FILE_KIND = "qsid-view-codes"
_PATH = re.compile(r"^/v/([A-Za-z]{6})/?$")


def new_code() -> str:
    return "".join(secrets.choice(CODE_LETTERS) for _ in range(CODE_LENGTH))


def normalize_code(text: str) -> str:
    """A code as typed (any case, spaces, or a whole link) -> the code.

    Raises
    ------
    InputError
        One line saying what a code looks like.
    """
    s = str(text or "").strip()
    m = re.search(r"/v/([A-Za-z]+)/?$", s)
    if m:
        s = m.group(1)
    s = s.lower()
    if len(s) != CODE_LENGTH or any(ch not in CODE_LETTERS for ch in s):
        raise InputError(
            f"view code {str(text).strip()[:40]!r} is not a code: a code is {CODE_LENGTH} letters "
            f"(a-z without i, l, o), like 'kqbxtr', or a view link"
        )
    return s


def code_from_path(path: str | None) -> str | None:
    """The code of a websocket path ``/v/CODE`` (None for any other path, e.g. ``/``)."""
    m = _PATH.match((path or "").partition("?")[0])
    return m.group(1).lower() if m else None


def view_link(host: str, code: str) -> str:
    """The link that opens ``code`` on the server reached as ``host`` (``name:port``)."""
    return f"http://{host}/?websocket=ws://{host}/v/{code}"


def default_store_path() -> Path:
    """``$QSID_CACHE_DIR/views.json``, else ``$XDG_CACHE_HOME/qsid/views.json``, else ``~/.cache/qsid/views.json``."""
    if os.environ.get("QSID_CACHE_DIR"):
        return Path(os.environ["QSID_CACHE_DIR"]) / "views.json"
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "qsid" / "views.json"


class ViewStore:
    """Settings per view code, bounded, optionally kept in a JSON file (thread-safe).

    Parameters
    ----------
    path : path-like, optional
        The file (read at start, written at most every :data:`WRITE_EVERY` s and by :meth:`flush`); None: memory only.
    max_views : int
        Codes kept; the least recently used are dropped.
    """

    def __init__(self, path: str | Path | None = None, max_views: int = MAX_VIEWS):
        self.path = None if path is None else Path(path)
        self.max_views = max(1, int(max_views))
        self._lock = threading.Lock()
        self._views: OrderedDict = OrderedDict()  # code -> settings JSON text (least recently used first)
        self._dirty = False
        self._written = 0.0
        self.load_note: str | None = None  # why the file could not be read (None: read, or no file)
        if self.path is not None:
            self._read()

    def _read(self) -> None:
        if self.path is None:
            return
        try:
            d = json.loads(self.path.read_text(encoding="utf-8"))
        except FileNotFoundError:
            return
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            self.load_note = f"view codes file {self.path} not read ({type(exc).__name__}); starting empty"
            return
        views = d.get("views") if isinstance(d, dict) and d.get("kind") == _FILE_KIND else None
        if not isinstance(views, dict):
            self.load_note = f"view codes file {self.path} is not a qsid view-codes file; starting empty"
            return
        for code, text in list(views.items())[-self.max_views :]:
            try:
                values_from_json(text)  # only settings the dashboard accepts come back
                self._views[normalize_code(code)] = text
            except (InputError, TypeError):
                continue

    def __len__(self) -> int:
        with self._lock:
            return len(self._views)

    def __contains__(self, code: str) -> bool:
        with self._lock:
            return code in self._views

    def get(self, code: str) -> Values | None:
        """The settings of ``code`` (None if unknown); marks it recently used."""
        with self._lock:
            text = self._views.get(code)
            if text is None:
                return None
            self._views.move_to_end(code)
        return values_from_json(text)

    def put(self, code: str, values: Values) -> None:
        """Keep ``values`` as the settings of ``code`` (written to the file soon)."""
        text = settings_json(values)
        with self._lock:
            if self._views.get(code) == text:
                self._views.move_to_end(code)
                return
            self._views[code] = text
            self._views.move_to_end(code)
            while len(self._views) > self.max_views:
                self._views.popitem(last=False)
            self._dirty = True
            due = time.monotonic() - self._written >= WRITE_EVERY
        if due:
            self.flush()

    def new_code(self) -> str:
        """A code not in use."""
        while True:
            code = new_code()
            if code not in self:
                return code

    def flush(self) -> None:
        """Write the file now if anything changed (atomically: a temporary file renamed over it)."""
        if self.path is None:
            return
        with self._lock:
            if not self._dirty:
                return
            doc = json.dumps({"kind": _FILE_KIND, "version": 1, "views": dict(self._views)})
            self._dirty = False
            self._written = time.monotonic()
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            tmp = self.path.with_name(f".{self.path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
            tmp.write_text(doc, encoding="utf-8")
            os.replace(tmp, self.path)
        except OSError as exc:  # the codes still work in memory
            self.load_note = f"view codes file {self.path} not written: {exc.strerror or exc}"


def url_script(link: str, nonce: int) -> str:
    """HTML that sets the tab's address bar to ``link`` (so that a reload opens the same view): an image that
    fails to load at once runs the one line (viser has no server call that runs a script in the page)."""
    query = link[link.index("?") :]
    script = f"if(location.search!=={json.dumps(query)}){{history.replaceState(null,'',{json.dumps(query)});}}"
    return (
        f'<img alt="" data-qsid-url="{nonce}" src="data:," style="display:none" '
        f'onerror="{html.escape(script, quote=True)}">'
    )


@dataclass(frozen=True)
class ViewOpen:
    """How a tab was opened: its code, the host the browser reached, whether the code is new (the address bar is
    then rewritten to the link) and a note for the panel (an unknown or malformed code in the link)."""

    code: str
    host: str
    fresh: bool = True
    note: str = ""


def open_view(
    store: ViewStore, path: str | None, host: str, defaults: Values, in_use: Callable[[str], bool] | None = None
) -> tuple[Values, ViewOpen]:
    """The settings and view of a tab whose websocket was opened at ``path`` (``/`` or ``/v/CODE``).

    ``in_use(code)``: True while another open tab shows that code. A link opened while its tab is still open (a
    class opening the teacher's link) gives the new tab the link's settings under a code of its own, so nothing
    done there changes the teacher's view; a reload (the old tab gone) keeps the code."""
    code = code_from_path(path)
    if code is None:
        note = ""
        if (path or "/").partition("?")[0].strip("/"):
            note = f"⚠️ The link's path {str(path)[:40]!r} holds no view code; this tab got a new one."
        return defaults, ViewOpen(store.new_code(), host, True, note)
    try:
        v = store.get(code)
    except InputError as exc:  # kept by an older version and no longer accepted
        v, why = None, f" ({exc})"
    else:
        why = ""
    if v is None:
        note = (
            f"⚠️ View code **{code}** is not known on this server{why}: this tab starts from the defaults and "
            "keeps the code from now on."
        )
        return defaults, ViewOpen(code, host, False, note)
    if in_use is not None and in_use(code):
        own = store.new_code()
        note = (
            f"Opened from view **{code}**, which another tab shows: this tab has its own code **{own}**, so "
            "changes here never change that tab."
        )
        return v, ViewOpen(own, host, True, note)
    return v, ViewOpen(code, host, False, "")


@dataclass
class CodePanel:
    """The tab's code line, the "load view code" box, its status line and the address-bar setter."""

    view: ViewOpen
    line: Any  # viser GUI handles (markdown, text, markdown, html)
    box: Any
    status: Any
    url: Any


def _say(panel: CodePanel, text: str) -> None:
    panel.status.content = text
    panel.status.visible = bool(text)


def load_code(panel: CodePanel, store: ViewStore, text: str, receive: Callable[[Values], None]) -> None:
    """The "load view code" box: hand the settings of the code (or link) typed to ``receive``, or say in one
    line why not."""
    if not str(text or "").strip():  # the box emptied (by the tab after a load): the status line stays
        return
    try:
        code = normalize_code(text)
        v = store.get(code)
    except InputError as exc:
        _say(panel, f"⚠️ {exc}")
        return
    if v is None:
        _say(panel, f"⚠️ view code **{code}** is not known on this server (ask for the link or check the letters)")
        return
    _say(panel, f"Loaded view **{code}** (this tab keeps its own code **{panel.view.code}**).")
    panel.box.value = ""  # emptied: the same code typed again is a change again, and loads again
    receive(v)


def add_code_panel(
    gui: Any, view: ViewOpen, after: Any, store: ViewStore, receive: Callable[[Values], None]
) -> CodePanel:
    """The code line and the load box, placed right after the panel element ``after`` (built once per tab).

    ``gui`` is the tab's ``viser.GuiApi``; a code typed in the box hands its settings to ``receive``.
    """
    link = view_link(view.host, view.code)
    order = float(after.order)
    line = gui.add_markdown(
        f"view code **{view.code}** · [link]({link}) (a reload or this link brings these settings back)",
        order=order + 0.001,
    )
    box = gui.add_text(
        "load view code",
        "",
        hint="Type a code (6 letters) or paste a view link: this tab takes that view's settings",
        order=order + 0.002,
    )
    status = gui.add_markdown(view.note, visible=bool(view.note), order=order + 0.003)
    url = gui.add_html(url_script(link, 1) if view.fresh else "", visible=view.fresh, order=order + 0.004)
    panel = CodePanel(view, line, box, status, url)
    box.on_update(lambda e: load_code(panel, store, e.target.value, receive))
    return panel


def remember(panel: CodePanel, store: ViewStore, values: Values) -> None:
    """After a frame is drawn: the tab's code keeps its newest settings."""
    store.put(panel.view.code, values)
