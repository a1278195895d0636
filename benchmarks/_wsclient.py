"""A minimal viser websocket client: what a browser tab sends and reads, without a browser.

Used by the soak/flood tests (``tests/system/test_dashboard_load.py``) and ``benchmarks/bench_soak.py``; the
camera message, the connection and the process helpers are :mod:`_support`'s (shared with the tests).
Speaks viser's wire protocol: msgpack messages to the server; from the server, frames of
``[8 B size][8 B zstd size][zstd msgpack {"messages": [...]}][binary buffers]``.
It learns each input's uuid from the server's ``Gui*Message`` (by label) and
follows every markdown's content, so it can tell when the tab says "ready".
"""

from __future__ import annotations

import threading
import time

import msgspec
import zstandard
from _support import CAMERA, connect_ws, family, family_rss, rss_mb

__all__ = ["WsTab", "rss_mb", "family", "family_rss"]  # the process helpers are _support's

#: How the tab's status line starts (any other markdown is not the status).
STATUS_STARTS = ("ready", "computing", "error", "starting", "queued")

#: The keys a markdown's text arrives under (viser >= 1.0: "_markdown"; older: "content").
_TEXT_KEYS = ("_markdown", "content")


class WsTab:
    """One tab over the websocket: ``send(label, value)`` as a browser would; ``ready`` when it says so."""

    def __init__(self, url: str, timeout: float = 30.0):
        self.ws = connect_ws(url, open_timeout=timeout, close_timeout=2)
        self.uuids: dict[str, str] = {}  # input label -> uuid
        self.markdown: dict[str, str] = {}  # markdown uuid -> content
        self.values: dict[str, object] = {}  # input uuid -> its value as the server last said
        self.sent_back: list[tuple[float, str, object]] = []  # (monotonic time, uuid, value) of every value update
        self.received = 0
        self.closed = False
        self.close_reason = ""  # why the connection ended, as the reader saw it
        self.statuses: list[tuple[float, str]] = []  # (monotonic time, text) of every status line received
        self._dz = zstandard.ZstdDecompressor()
        self._lock = threading.Lock()
        self.thread = threading.Thread(target=self._read, daemon=True)
        self.thread.start()
        self.ws.send(msgspec.msgpack.encode(CAMERA))  # viser counts a client once it reports its camera

    def _read(self) -> None:
        try:
            while True:
                raw = self.ws.recv()
                self.received += len(raw)
                if isinstance(raw, bytes) and len(raw) >= 16:
                    size = int.from_bytes(raw[8:16], "little")
                    payload = msgspec.msgpack.decode(self._dz.decompress(raw[16 : 16 + size]))
                    for m in payload.get("messages", ()):
                        self._note(m)
        except Exception as exc:
            self.close_reason = f"{type(exc).__name__}: {exc}"
            self.closed = True

    def _note(self, m: dict) -> None:
        typ = m.get("type", "")
        with self._lock:
            if typ == "GuiMarkdownMessage":
                props = m.get("props", {})
                self.markdown[m["uuid"]] = props.get("_markdown", props.get("content", ""))
            elif typ.startswith("Gui") and isinstance(m.get("props"), dict) and "label" in m["props"]:
                self.uuids[m["props"]["label"]] = m["uuid"]
                if "value" in m:  # viser 1.x sends an input's initial value beside its props
                    self.values[m["uuid"]] = m["value"]
            elif typ == "GuiUpdateMessage":
                up = m.get("updates", {})
                if "value" in up:
                    self.values[m["uuid"]] = up["value"]
                    self.sent_back.append((time.monotonic(), m["uuid"], up["value"]))
                for key in _TEXT_KEYS:  # viser 1.x sends a markdown's text as "_markdown"
                    if key in up:
                        self.markdown[m["uuid"]] = up[key]
                        if isinstance(up[key], str) and up[key].startswith(STATUS_STARTS):
                            self.statuses.append((time.monotonic(), up[key]))
            elif typ == "GuiRemoveMessage":  # e.g. the weight sliders of another system: forget their labels
                for label in [k for k, v in self.uuids.items() if v == m.get("uuid")]:
                    del self.uuids[label]

    def wait_for(self, label: str, timeout: float = 30.0) -> str:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            with self._lock:
                if label in self.uuids:
                    return self.uuids[label]
            time.sleep(0.02)
        raise TimeoutError(f"input {label!r} not shown within {timeout} s")

    @property
    def status(self) -> str:
        """The status line ("ready · ...", "computing ...", "error ...")."""
        with self._lock:
            texts = list(self.markdown.values())
        return next((t for t in texts if t.startswith(STATUS_STARTS)), "")

    @property
    def ready(self) -> bool:
        return self.status.startswith("ready")

    def wait_ready(self, timeout: float = 60.0) -> float:
        """Seconds until the tab says ready (TimeoutError otherwise)."""
        t0 = time.monotonic()
        while time.monotonic() - t0 < timeout:
            if self.ready:
                return time.monotonic() - t0
            if self.closed:
                raise ConnectionError(f"the connection ended ({self.close_reason})")
            time.sleep(0.02)
        raise TimeoutError(f"the tab was not ready within {timeout} s (status: {self.status!r})")

    def labels(self, prefix: str) -> list[str]:
        """The labels of the inputs shown now that start with ``prefix``."""
        with self._lock:
            return sorted(k for k in self.uuids if k.startswith(prefix))

    def answer_after(self, index: int, timeout: float) -> tuple[float, str]:
        """The first "ready" or "error" status line after ``statuses[index - 1]``: (time it arrived, text)."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            with self._lock:
                hit = next((s for s in self.statuses[index:] if s[1].startswith(("ready", "error"))), None)
            if hit is not None:
                return hit
            if self.closed:
                raise ConnectionError(f"the connection ended ({self.close_reason})")
            time.sleep(0.01)
        raise TimeoutError(f"no answer within {timeout} s (status: {self.status!r})")

    def value(self, label: str) -> object:
        """The value of input ``label`` as the server last said (None if unknown)."""
        with self._lock:
            return self.values.get(self.uuids.get(label, ""))

    def send(self, label: str, value) -> None:
        """Set input ``label`` to ``value`` exactly as a browser does (no range check on this side).

        viser calls no callback for a value equal to the one it holds: such a send changes nothing.
        """
        uuid = self.uuids.get(label) or self.wait_for(label)
        with self._lock:
            self.values[uuid] = value
        self.ws.send(msgspec.msgpack.encode({"type": "GuiUpdateMessage", "uuid": uuid, "updates": {"value": value}}))

    def close(self) -> None:
        try:
            self.ws.close()
        except Exception:
            pass
