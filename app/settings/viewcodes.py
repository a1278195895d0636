"""Views that survive a reload and travel: a short code per tab whose settings the server keeps, and the links.

Every tab has a view code (six letters). Its settings are kept on the server (:class:`ViewStore`: in memory and
in a small JSON file under the user's cache directory, at most :data:`MAX_VIEWS` codes, the least recently used
dropped first) and updated each time the tab draws new settings.

viser's client connects its websocket to the address in the page's ``?websocket=`` parameter, path included,
and keeps that parameter in the address bar, so a reload connects to the same path again; the server reads the
path of the websocket request (the dashboard's :func:`app.dashboard.viserfix.connection_request`). The paths (:func:`parse_path`):

``/v/CODE``      the view CODE (its settings; a tab of its own if another tab shows CODE)
``/n/CODE``      the same for a code the server itself handed out: no note if it has no settings yet
``/f/CODE``      follow the view CODE live and read-only (the dashboard's :mod:`app.dashboard.follow`)

each optionally followed by ``/SPARE``, a second code: the code this tab takes as its own when CODE is not
its own (another tab shows CODE, or the follower explores from here), so that the address bar already holds
what a reload needs. The server hands those addresses out by an HTTP redirect of the page request
(:func:`page_location`, installed by :func:`app.dashboard.viserfix.redirect_pages`): the bare address ``/``,
the short links ``/v/CODE`` and ``/f/CODE`` the panel shows, and a long link without a spare. No script runs
in the page to rewrite its address.
"""

from __future__ import annotations

import functools
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
from urllib.parse import parse_qsl, quote

from .files import settings_json, values_from_json
from .values import InputError, Values

__all__ = [
    "ViewStore",
    "MAX_VIEWS",
    "CODE_LETTERS",
    "new_code",
    "normalize_code",
    "code_from_path",
    "parse_path",
    "view_link",
    "page_location",
    "default_store_path",
    "ViewOpen",
    "open_view",
]

#: Letters of a code: lower case without i, l, o (not to be confused with 1 and 0 when read off a projector).
CODE_LETTERS = "abcdefghjkmnpqrstuvwxyz"
CODE_LENGTH = 6
#: Codes kept (memory and file); the least recently used beyond that are dropped.
MAX_VIEWS = 1000
#: Seconds between two writes of the file (the newest settings are written at the latest on close).
WRITE_EVERY = 2.0
_FILE_KIND = "qsid-view-codes"
#: A websocket path: kind, code (checked later: a malformed one is a note), optional spare code.
_PATH = re.compile(r"^/([nvf])/([^/?#]{1,40})(?:/([A-Za-z]{6}))?/?$")
#: A page request of a short link (``/v/CODE``, ``/f/CODE``).
_SHORT = re.compile(r"^/([vf])/([^/?#]{1,40})/?$")
#: The ``?websocket=`` value of a long link without a spare.
_LONG = re.compile(r"^(wss?)://([^/?#]+)/([nvf])/([A-Za-z]{6})/?$")
#: A Host header the server may write back into a link (name or IPv4 or [IPv6], optional port).
_HOST = re.compile(r"^(?:[A-Za-z0-9.-]+|\[[0-9A-Fa-f:.]+\])(?::[0-9]{1,5})?$")


def new_code() -> str:
    return "".join(secrets.choice(CODE_LETTERS) for _ in range(CODE_LENGTH))


def normalize_code(text: str) -> str:
    """A code as typed (any case, spaces, or a whole link, view or follow) -> the code.

    Raises
    ------
    InputError
        One line saying what a code looks like.
    """
    s = str(text or "").strip()
    m = re.search(r"/[nvf]/([A-Za-z]+)(?:/[A-Za-z]{6})?/?$", s)
    if m:
        s = m.group(1)
    s = s.lower()
    if len(s) != CODE_LENGTH or any(ch not in CODE_LETTERS for ch in s):
        raise InputError(
            f"view code {str(text).strip()[:40]!r} is not a code: a code is {CODE_LENGTH} letters "
            f"(a-z without i, l, o), like 'kqbxtr', or a view link"
        )
    return s


def parse_path(path: str | None) -> tuple[str, str, str | None] | None:
    """(kind, code as written, spare code or None) of a websocket path ``/v/CODE[/SPARE]`` (also ``n``, ``f``);
    None for any other path (e.g. ``/``). The code is as written (:func:`normalize_code` checks it)."""
    m = _PATH.match((path or "").partition("?")[0])
    if m is None:
        return None
    return m.group(1), m.group(2), (m.group(3).lower() if m.group(3) else None)


def code_from_path(path: str | None) -> str | None:
    """The (well-formed) code of a websocket path ``/v/CODE`` (None for any other path, e.g. ``/``)."""
    parsed = parse_path(path)
    try:
        return normalize_code(parsed[1]) if parsed is not None else None
    except InputError:
        return None


def view_link(host: str, code: str, kind: str = "v", short: bool = False) -> str:
    """The link that opens ``code`` on the server reached as ``host`` (``name:port``); ``kind`` ``"f"``: the
    follow link. ``short``: ``http://HOST/v/CODE``, which only a server redirecting page requests answers
    (:func:`page_location`); otherwise the long form every viser serves."""
    if short:
        return f"http://{host}/{kind}/{code}"
    return f"http://{host}/?websocket=ws://{host}/{kind}/{code}"


def page_location(target: str, host: str, secure: bool, fresh: Callable[[], str]) -> str | None:
    """Where a page request for ``target`` (path and query) is redirected to, or None (served as it is).

    The bare address gets a new code (``/n/NEW/SPARE``), a short link ``/v/CODE`` or ``/f/CODE`` and a long link
    without a spare get a spare code (``/v/CODE/SPARE``): the address bar then holds everything a reload needs.
    ``host`` is the request's Host header (a link names it; a malformed one gives None), ``secure`` whether the
    page was reached over https (through a proxy: the websocket is then ``wss://``), ``fresh()`` a code not in use.
    """
    if not _HOST.match(host or ""):
        return None
    path, _, query = target.partition("?")
    params = parse_qsl(query, keep_blank_values=True)
    sockets = [v for k, v in params if k == "websocket"]
    others = "".join(f"&{quote(k)}={quote(v)}" for k, v in params if k != "websocket")
    short = _SHORT.match(path)
    if short is not None:  # (a malformed code is kept, quoted: the tab then says what a code looks like)
        token = short.group(2)
        code = token.lower() if token.isascii() and token.isalpha() else quote(token, safe="")
        base, kind = f"{'wss' if secure else 'ws'}://{host}", short.group(1)
    elif path == "/" and not sockets:
        base, kind, code = f"{'wss' if secure else 'ws'}://{host}", "n", fresh()
    elif path == "/" and len(sockets) == 1 and (long := _LONG.match(sockets[0])) is not None:
        base, kind, code = f"{long.group(1)}://{long.group(2)}", long.group(3), long.group(4)
    else:
        return None
    return f"/?websocket={base}/{kind}/{code}/{fresh()}{others}"


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
        # each tab of a class puts the same settings after every frame: their JSON (~0.5 ms) made once
        self._json = functools.lru_cache(maxsize=64)(settings_json)
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
        text = self._json(values)
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


@dataclass(frozen=True)
class ViewOpen:
    """How a tab was opened and what it is now.

    Attributes
    ----------
    code : str
        The tab's own code (a follower: the code it takes when it explores from here).
    host : str
        The host (``name:port``) the browser reached: the links name it.
    note : str
        One line for the panel (an unknown or malformed code, a code another tab shows), or "".
    follow : str or None
        The code this tab follows read-only (None: a view of its own).
    kept : bool
        Whether a reload of the tab's address comes back to ``code`` (False: the panel says how to come back).
    short : bool
        Links in the short form (the server redirects page requests, :func:`page_location`).
    """

    code: str
    host: str
    note: str = ""
    follow: str | None = None
    kept: bool = True
    short: bool = False


def _stored(store: ViewStore, code: str) -> tuple[Values | None, str]:
    """The settings of ``code`` (None if unknown) and why they are not usable ("" or " (reason)")."""
    try:
        return store.get(code), ""
    except InputError as exc:  # kept by an older version and no longer accepted
        return None, f" ({exc})"


def open_view(
    store: ViewStore, path: str | None, host: str, defaults: Values, in_use: Callable[[str], bool] | None = None
) -> tuple[Values, ViewOpen]:
    """The settings and view of a tab whose websocket was opened at ``path`` (see the module docstring).

    ``in_use(code)``: True while another open tab shows that code as its own. A view link opened while its tab is
    still open (a class opening the teacher's link) gives the new tab the link's settings under a code of its
    own (the path's spare if it has one), so nothing done there changes the teacher's view; a reload (the old tab
    gone) keeps the code. A spare that already has settings is this tab's own (it took it before: a reload).
    """
    busy = in_use or (lambda _code: False)
    parsed = parse_path(path)
    if parsed is None:
        note = ""
        if (path or "/").partition("?")[0].strip("/"):
            note = f"⚠️ The link's path {str(path)[:40]!r} holds no view code; this tab got a new one."
        return defaults, ViewOpen(store.new_code(), host, note, kept=False)
    kind, text, spare = parsed
    own = spare if spare is not None and not busy(spare) else None
    if own is not None:
        v, _ = _stored(store, own)
        if v is not None:  # this tab made the spare its own before (a fork or "explore from here"): a reload
            return v, ViewOpen(own, host)
    mine, kept = (own, True) if own is not None else (store.new_code(), False)
    try:
        code = normalize_code(text)
    except InputError as exc:
        return defaults, ViewOpen(mine, host, f"⚠️ The link's {exc}; this tab shows the default view.", kept=kept)
    v, why = _stored(store, code)
    if kind == "f":
        if v is None:
            note = (
                f"⚠️ View code **{code}** is not known on this server{why}: there is nothing to follow; this tab "
                "shows the default view, as a view of its own."
            )
            return defaults, ViewOpen(mine, host, note, kept=kept)
        return v, ViewOpen(mine, host, follow=code, kept=kept)
    if v is None:
        note = ""
        if kind == "v":  # ("n": a code the server handed out, no settings yet: a new tab)
            note = (
                f"⚠️ View code **{code}** is not known on this server{why}: this tab starts from the defaults "
                "and keeps the code from now on."
            )
        return defaults, ViewOpen(code, host, note)
    if busy(code):
        note = (
            f"Opened from view **{code}**, which another tab shows: this tab has its own code **{mine}**, so "
            "changes here never change that tab."
        )
        return v, ViewOpen(mine, host, note, kept=kept)
    return v, ViewOpen(code, host)
