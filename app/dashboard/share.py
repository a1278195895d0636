"""Keep and share a view: settings as JSON (download / upload / ``--settings FILE``), a plant file as the
panel's custom system (``--system FILE``), and the tab's "Save, load & export" folder, whose command line and
exports come from :mod:`app.dashboard.exports`.

The pure functions (settings <-> JSON, plant file -> values) are tested directly; :func:`add_share_panel` builds
the tab's folder from what it needs (the last frame, the panel's values, a way to send a file and to hand
loaded settings back) and :func:`show_frame` shows the command of a frame drawn.
"""

from __future__ import annotations

import dataclasses
import html
import json
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from app.settings.check import check_setting
from app.settings.schema import BY_NAME
from qsid_core import QsidError

from .controls import CONTROLS
from .exports import command_lines, curves_csv, curves_json, frame_html
from .koopman_settings import NONLINEAR_CHOICES, koopman_config, nonlinear_values
from .settings import InputError, Values, resolve_system, sweep_config

if TYPE_CHECKING:
    from .frames import Frame

__all__ = [
    "SETTINGS_KIND",
    "settings_json",
    "values_from_json",
    "load_settings_file",
    "values_for_plant_file",
    "apply_values",
    "add_share_panel",
    "show_frame",
    "ShareHandles",
]

#: The "kind" tag of a settings file (and its format version).
SETTINGS_KIND, SETTINGS_VERSION = "qsid-dashboard-settings", 1
_FIELDS = {f.name: f for f in dataclasses.fields(Values)}
_CONTROL = {c.name: c for c in CONTROLS}


def settings_json(v: Values) -> str:
    """The panel's settings as a small JSON document (what "Download settings" saves)."""
    return json.dumps(
        {"kind": SETTINGS_KIND, "version": SETTINGS_VERSION, "values": dataclasses.asdict(v)}, indent=2, allow_nan=False
    )


def _field_value(name: str, value: object) -> object:
    """``value`` of the settings file's field ``name``, checked by the settings table's rules (its type before
    any conversion, its range, its choices) as a panel value is; InputError in plain words if it is refused."""
    c = _CONTROL.get(name)
    options = c.choices if c is not None and c.choices else None
    try:
        return check_setting(BY_NAME[name], value, options, name=name)
    except InputError as exc:
        raise InputError(f"settings: {exc}") from None


def values_from_json(text: str | bytes) -> Values:
    """Settings saved by :func:`settings_json` back as :class:`Values` (checked: the engine accepts them).

    Missing fields keep their defaults; unknown fields, wrong types and values the engine refuses raise
    :class:`~app.dashboard.settings.InputError` (one line).
    """
    try:
        d = json.loads(text)
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise InputError(f"settings: not a JSON file ({getattr(exc, 'msg', type(exc).__name__)})") from None
    if not isinstance(d, dict) or d.get("kind") != SETTINGS_KIND or not isinstance(d.get("values"), dict):
        raise InputError(f'settings: not a qsid settings file (needs "kind": "{SETTINGS_KIND}" and "values")')
    unknown = sorted(set(d["values"]) - set(_FIELDS))
    if unknown:
        raise InputError(f"settings: unknown field(s) {', '.join(map(str, unknown))[:200]}")
    v = Values(**{k: _field_value(k, x) for k, x in d["values"].items()})
    if v.system in NONLINEAR_CHOICES:  # a nonlinear preset: its sweep's configuration instead
        koopman_config(v)
    else:
        sweep_config(v, resolve_system(v).system)  # every value usable (InputError in plain words otherwise)
    return v


def load_settings_file(path: str | Path) -> Values:
    """``qsid-dashboard --settings FILE``: the file's settings (InputError naming the file if bad)."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"settings file {str(p)!r} " + ("is a directory" if p.is_dir() else "does not exist"))
    try:
        return values_from_json(p.read_bytes())
    except InputError as exc:
        raise InputError(f"{p.name}: {exc}") from None
    except OSError as exc:
        raise InputError(f"cannot read settings file {str(p)!r}: {exc.strerror or exc}") from None


def values_for_plant_file(path: str | Path, defaults: Values) -> tuple[Values, list[str]]:
    """``qsid-dashboard --system FILE``: the plant file the CLI reads, as the panel's custom system.

    A, B and x0 are kept exactly (their numbers written out in full); Q and R become the weight
    sliders' log10 positions, so a weight outside the sliders' range is clipped and an off-diagonal
    entry dropped: each such change is one line of the returned notes.

    Raises
    ------
    InputError
        The file cannot be read or is not a plant the engine and the panel accept (one line, naming it).
    """
    from qsid_core import get_system
    from qsid_core.plant import get_nonlinear, is_nonlinear_file

    from .settings import LOG_MAX, LOG_MIN, MAX_CUSTOM_STATES, log_from_weights

    if is_nonlinear_file(path):  # a vector field: a nonlinear plant of its own in the system dropdown
        try:
            get_nonlinear(str(path))
        except QsidError as exc:
            raise InputError(f"--system {path}: {exc}") from None
        return nonlinear_values(str(path), defaults), []

    try:
        sysm = get_system(str(path))  # a preset name or a file, as qsid --system
    except QsidError as exc:
        raise InputError(f"--system {path}: {exc}") from None
    if sysm.n > MAX_CUSTOM_STATES:
        raise InputError(
            f"--system {path}: {sysm.n} states; the dashboard's panel takes at most {MAX_CUSTOM_STATES} "
            "(the CLI takes any size the engine accepts)"
        )
    rows = lambda M: "; ".join(" ".join(repr(float(x)) for x in row) for row in M)  # noqa: E731
    notes = []
    Q, R = np.asarray(sysm.Q, dtype=float), np.asarray(sysm.R, dtype=float)
    for name, W in (("Q", Q), ("R", R)):
        d = np.diag(W)
        if np.any(W != np.diag(d)):
            notes.append(f"{name} of {path} is not diagonal: the panel keeps its diagonal")
        if np.any((d > 0) & ((d < 10.0**LOG_MIN) | (d > 10.0**LOG_MAX))):
            notes.append(
                f"{name} of {path} = diag({', '.join(f'{w:g}' for w in d)}) is outside the sliders' range "
                f"1e{LOG_MIN:g}..1e{LOG_MAX:g}: clipped"
            )
    v = defaults.replace(
        system="custom",
        a_text=rows(sysm.A),
        b_text=rows(sysm.B),
        x0=", ".join(repr(float(x)) for x in np.asarray(sysm.x0, dtype=float)),
        log_q=log_from_weights(np.diag(Q)),
        log_r=log_from_weights(np.diag(R)),
    )
    resolve_system(v)  # the panel's own checks, now rather than in the first tab
    return v, notes


# ----- the panel (session hooks) -------------------------------------------------------------------------------
@dataclasses.dataclass
class ShareHandles:
    """The "Keep & share" folder of one tab: command text, status line, and a settings upload waiting."""

    command: Any  # viser markdown handles
    status: Any
    pending: Values | None = None
    shown: Values | None = None


def apply_values(el, v: Values) -> None:
    """Set every input of a tab's panel to ``v`` (from the tab's worker thread)."""
    from .controls import initial_value, set_system

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
