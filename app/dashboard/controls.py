"""The control panel of one browser tab, built from ONE table of control specs (:data:`CONTROLS`).

Like viser's SMPL example (``examples/04_demos/03_smpl_visualizer.py``),
:func:`make_gui_elements` builds every handle into one :class:`GuiElements`
dataclass; every input's callback only marks the tab dirty (``on_change``); the
tab's one worker loop (:mod:`app.dashboard.session`) reads :func:`read_values`
and redraws. Choices and ranges come from the engine (via
:mod:`app.settings.values`); the slider ranges here are the panel's own.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from app.figures.phase_scene import axes_options
from app.lessons.drift import lesson_markdown
from app.lessons.table import NONE, lesson_values
from app.settings.files import panel_choices
from app.settings.schema import BY_NAME, SETTINGS, Setting, hint_text, resolve
from app.settings.values import (
    INTERACTIVE,
    LOG_MAX,
    LOG_MIN,
    PAPER_SCALE,
    Values,
    format_weights,
    is_nonlinear,
    log_from_weights,
    matrix_text,
    scale_for,
    weights_from_log,
)
from qsid_core import LTISystem

from .flow import inline

if TYPE_CHECKING:
    import viser

__all__ = [
    "Control",
    "CONTROLS",
    "GuiElements",
    "make_gui_elements",
    "read_values",
    "panel_form",
    "initial_value",
    "set_scale",
    "set_system",
    "apply_lesson",
    "PLAY_LABEL",
]

#: The auto-play button's label when it would start (b from 1 to 16) and what it does.
PLAY_LABEL = "▶ auto-play b = 1 → 16"
PLAY_HINT = (
    "Steps the word length from 1 to 16, about one b per second (the next b only once the previous one is drawn); "
    "press again to pause or resume. Any change of yours stops it."
)
MATRIX_HINT: str = BY_NAME["a_text"].hint or ""


@dataclass(frozen=True)
class Control:
    """One input of the panel, made from one row of the settings table (``setting``); ``name`` is the
    :class:`~app.settings.values.Values` field it sets.

    ``kind``: slider (lo, hi, step), dropdown (choices), text, checkbox, number (lo, hi, step);
    ``tab``: panel tab ("" = above the tabs); ``folder``: optional folder inside the tab;
    ``convert``: the setting's type.
    """

    name: str
    kind: str
    label: str
    tab: str = ""
    lo: float | None = None
    hi: float | None = None
    step: float | None = None
    choices: tuple[str, ...] = ()
    hint: str | None = None
    folder: str | None = None
    convert: Callable[[Any], Any] = str
    setting: Setting | None = None


def _control(s: Setting) -> Control:
    """The panel input of setting ``s``."""
    assert s.control is not None
    if s.slider is not None:
        lo, hi, step = resolve(s.slider)
    else:  # a number box: the range is the server's (the box has no bound: see _add)
        lo, hi, step = s.min, s.max, s.step
    choices = panel_choices(s)  # a front end's own (lessons, systems, identification) or the engine's
    return Control(s.name, s.control, s.label, s.tab, lo, hi, step, choices, hint_text(s), s.folder, s.type, s)


#: Every input of the panel, in display order (tabs appear in order of first use): the settings table's
#: rows that have a panel input.
CONTROLS: tuple[Control, ...] = tuple(_control(s) for s in SETTINGS if s.control is not None)


@dataclass
class GuiElements:
    """Every handle of one tab's panel.

    ``inputs`` maps each :data:`CONTROLS` name to its handle; ``q_sliders`` /
    ``r_sliders`` are the log10 weight sliders (rebuilt when the system changes).
    """

    gui: viser.GuiApi
    inputs: dict[str, Any]  # handles of several kinds (slider, dropdown, text, ...)
    # viser's stubs make a progress bar's ``value`` read-only (its setter is not next to its getter)
    progress: Any
    status: viser.GuiMarkdownHandle
    error: viser.GuiMarkdownHandle
    summary: viser.GuiMarkdownHandle
    system_note: viser.GuiMarkdownHandle
    weights_note: viser.GuiMarkdownHandle
    lesson_text: viser.GuiMarkdownHandle
    play: viser.GuiButtonHandle
    q_folder: viser.GuiFolderHandle
    r_folder: viser.GuiFolderHandle
    tabs: viser.GuiTabGroupHandle  # the settings tabs (System, Quantizer, ...)
    summary_folder: viser.GuiFolderHandle
    on_change: Callable[..., None]
    q_sliders: list[viser.GuiSliderHandle[float]] = field(default_factory=list)
    r_sliders: list[viser.GuiSliderHandle[float]] = field(default_factory=list)
    system_key: tuple[Any, ...] | None = None
    theory_note: viser.GuiMarkdownHandle | None = None  # shown for a nonlinear plant in the Theory tab
    scale_buttons: list[viser.GuiButtonHandle] = field(default_factory=list)  # paper scale, interactive

    def __getitem__(self, name: str) -> Any:
        return self.inputs[name]


def initial_value(c: Control, v: Values, system: LTISystem) -> Any:
    """The first value of control ``c`` (empty texts show the system's matrices and x0)."""
    if c.name == "a_text":
        return v.a_text or matrix_text(system.A)
    if c.name == "b_text":
        return v.b_text or matrix_text(system.B)
    if c.name == "x0":
        assert system.x0 is not None  # LTISystem fills x0 in __post_init__
        return v.x0 or ", ".join(f"{x:g}" for x in system.x0)
    if c.name == "axes":
        opts = axes_options(system.state_names)
        return v.axes if v.axes in opts else opts[0]
    return c.convert(getattr(v, c.name))


def _add(gui: viser.GuiApi, c: Control, value: Any, system: LTISystem, custom: bool) -> Any:
    """The viser handle of control ``c`` (kind-specific arguments; visibility and locks set here)."""
    if c.kind == "slider":
        assert c.lo is not None and c.hi is not None and c.step is not None  # every slider has a range and step
        return gui.add_slider(c.label, c.lo, c.hi, c.step, value, hint=c.hint)
    if c.kind == "number":  # no bound in the browser's box: it would clamp a refused value on leaving the box, racing
        # the value in use the server sends back (the range is checked by the server: inputs.check_sent)
        h = gui.add_number(c.label, value, min=c.lo, step=c.step, hint=c.hint)  # (min: for the decimals offered)
        h.min = None
        return h
    if c.kind == "checkbox":
        return gui.add_checkbox(c.label, value, hint=c.hint)
    if c.kind == "dropdown":
        choices: tuple[str, ...] = c.choices or tuple(axes_options(system.state_names))
        if c.name == "system" and value not in choices and is_nonlinear(value):  # a nonlinear plant file
            choices = (*choices[:-1], value, choices[-1])
        return gui.add_dropdown(c.label, choices, initial_value=value, hint=c.hint)
    if c.name in ("a_text", "b_text"):
        return gui.add_text(c.label, value, multiline=True, disabled=not custom, hint=c.hint)
    return gui.add_text(c.label, value, hint=c.hint)


def _extras_after(gui: viser.GuiApi, name: str, values: Values, handles: dict[str, Any], extra: dict[str, Any]) -> None:
    """The panel's non-input parts (notes, weight folders, scale buttons), placed after control ``name``."""
    if name == "b_text":
        extra["system_note"] = gui.add_markdown(_system_note(values.system))
    elif name == "data_seed":
        paper = gui.add_button(
            f"Paper scale ({PAPER_SCALE['trajectories']} × {PAPER_SCALE['steps']}, "
            f"{PAPER_SCALE['realizations']} realizations)",
            hint="The letter's data size; the first full update takes a few seconds",
        )
        inter = gui.add_button(
            f"Interactive ({INTERACTIVE['trajectories']} × {INTERACTIVE['steps']}, "
            f"{INTERACTIVE['realizations']} realizations)"
        )
        paper.on_click(lambda _: set_scale(handles, scale_for(handles["system"].value, paper=True)))
        inter.on_click(lambda _: set_scale(handles, scale_for(handles["system"].value, paper=False)))
        extra["scale_buttons"] = [paper, inter]
    elif name == "identification":
        gui.add_markdown(
            "LS is biased by the quantization noise (Theorem 1 for a linear plant); BCLS removes that bias "
            "(for a nonlinear plant exactly with a polynomial dictionary and subtractive dither). "
            "'LS + BCLS' draws both side by side (blue, red)."
        )
    elif name == "horizon":
        extra["q_folder"] = gui.add_folder("Q diagonal (slider = log10 weight)")
        extra["r_folder"] = gui.add_folder("R diagonal (slider = log10 weight)")
        extra["weights_note"] = gui.add_markdown("")


def make_gui_elements(
    gui: viser.GuiApi, values: Values, system: LTISystem, on_change: Callable[..., None]
) -> GuiElements:
    """Build the whole panel of a tab in ``gui`` (``client.gui``); every input calls ``on_change(user)``,
    ``user`` True when the change came from the browser."""
    gui.add_markdown("**qsid** · quantized data → identified model → MPC")
    handles: dict = {}
    extra: dict = {}
    custom = values.system == "custom"

    def add(c: Control) -> None:
        h = _add(gui, c, initial_value(c, values, system), system, custom)
        # only mark dirty (at once); the tab's worker redraws. A change from the browser (client_id set, not one
        # the server made) also counts as the person's own: it stops the auto-play.
        h.on_update(inline(lambda event: on_change(event.client_id is not None)))
        handles[c.name] = h

    for c in (c for c in CONTROLS if c.tab == ""):  # the lesson and the word length, above the tabs
        add(c)
        if c.name == "lesson":
            text = lesson_markdown(values.lesson)
            extra["lesson_text"] = gui.add_markdown(text, visible=bool(text))
        if c.name == "presenter":
            extra["play"] = gui.add_button(PLAY_LABEL, hint=PLAY_HINT)
    extra["progress"] = gui.add_progress_bar(0.0, animated=False)
    extra["status"] = gui.add_markdown("starting …")
    extra["error"] = gui.add_markdown("", visible=False)
    tabs = extra["tabs"] = gui.add_tab_group()
    for tab in dict.fromkeys(c.tab for c in CONTROLS if c.tab):
        with tabs.add_tab(tab):
            if tab == "Theory":  # (viser cannot hide a tab: for a nonlinear plant it says why it is empty)
                extra["theory_note"] = gui.add_markdown(THEORY_NOTE, visible=False)
            folders: dict = {}
            for c in (c for c in CONTROLS if c.tab == tab):
                if c.folder is None:
                    add(c)
                else:
                    if c.folder not in folders:  # (setdefault would build a new, empty folder every time)
                        folders[c.folder] = gui.add_folder(c.folder)
                    with folders[c.folder]:
                        add(c)
                _extras_after(gui, c.name, values, handles, extra)
    with gui.add_folder("Summary") as extra["summary_folder"]:
        extra["summary"] = gui.add_markdown("")
    handles["fixed_range"].visible = values.range_mode == "fixed"
    handles["rho"].disabled = bool(values.rho_auto)
    handles["axes"].visible = len(axes_options(system.state_names)) > 1
    el = GuiElements(gui=gui, inputs=handles, on_change=on_change, **extra)
    set_system(el, system, values.log_q, values.log_r, reset=False)
    return el


#: The Theory tab's text for a nonlinear plant (its settings are the linear theory's, hidden then).
THEORY_NOTE = (
    "The settings here (θ of Theorem 1's data, the ultimate bound's ρ and its plot) belong to the linear theory: "
    "for a nonlinear plant they are not used, and the Nonlinear plots show observed outcomes only."
)


def _system_note(name: str) -> str:
    if is_nonlinear(name):
        return (
            f"Nonlinear plant **{name}**: identified by Koopman/EDMD in the dictionary below, its Koopman MPC run on "
            "the true plant (settings a nonlinear plant does not use are hidden)."
        )
    if name == "custom":
        return "Type A (n × n) and B (n × m). " + MATRIX_HINT + " x0 = e1, Q = I, R = I by default."
    return f"Preset **{name}** (matrices shown read-only; pick 'custom' to edit a copy)."


def set_scale(handles: dict, scale: dict) -> None:
    """The paper-scale / interactive buttons: set trajectories, steps and realizations."""
    for name in ("trajectories", "steps", "realizations"):
        handles[name].value = scale[name]


def _weight_sliders(
    el: GuiElements, folder: viser.GuiFolderHandle, kind: str, names: Iterable[str], logs: Iterable[float]
) -> list[viser.GuiSliderHandle[float]]:
    with folder:
        sliders = [
            el.gui.add_slider(
                f"{kind} {nm}",
                LOG_MIN,
                LOG_MAX,
                0.1,
                float(x),
                hint=f"log10 of the weight of {'state' if kind == 'Q' else 'input'} {nm}",
            )
            for nm, x in zip(names, logs)
        ]
    for h in sliders:
        h.on_update(inline(lambda event: el.on_change(event.client_id is not None)))
    return sliders


def set_system(
    el: GuiElements, system: LTISystem, log_q: Sequence[float] = (), log_r: Sequence[float] = (), reset: bool = True
) -> bool:
    """Adapt the inputs to ``system``: A/B boxes, Q/R sliders, x0, 3-D axes. True if anything changed.

    Called by the tab's worker; the value changes it makes mark the tab dirty like
    any other, and the worker then sees that the panel values did not change.
    """
    key = (system.name, system.A.tobytes(), system.B.tobytes(), system.A.shape, system.B.shape)
    if key == el.system_key:
        return False
    first = el.system_key is None
    el.system_key = key
    h = el.inputs
    custom = h["system"].value == "custom"
    h["a_text"].disabled = not custom
    h["b_text"].disabled = not custom
    el.system_note.content = _system_note(h["system"].value)
    if not custom:
        h["a_text"].value = matrix_text(system.A)
        h["b_text"].value = matrix_text(system.B)
    assert system.Q is not None and system.R is not None and system.x0 is not None  # filled in __post_init__
    lq = tuple(log_q) if len(log_q) == system.n else log_from_weights(np.diag(system.Q))
    lr = tuple(log_r) if len(log_r) == system.m else log_from_weights(np.diag(system.R))
    for s in el.q_sliders + el.r_sliders:
        s.remove()
    el.q_sliders = _weight_sliders(el, el.q_folder, "Q", system.state_names, lq)
    el.r_sliders = _weight_sliders(el, el.r_folder, "R", system.input_names, lr)
    if reset and not first:
        h["x0"].value = ", ".join(f"{x:g}" for x in system.x0)
    opts = axes_options(system.state_names)
    h["axes"].options = opts
    h["axes"].visible = len(opts) > 1
    show_weights(el)
    return True


def show_weights(el: GuiElements) -> None:
    q = weights_from_log([s.value for s in el.q_sliders])
    r = weights_from_log([s.value for s in el.r_sliders])
    el.weights_note.content = f"{format_weights('Q', q)}, {format_weights('R', r)}"


def apply_lesson(el: GuiElements, name: str, resolve: Callable[[Values], LTISystem]) -> bool:
    """Set the panel to lesson ``name`` (system first, then every other input) and show its text.

    ``resolve(values) -> LTISystem`` builds the lesson's system. Returns True if inputs were set
    (False for no lesson: the panel stays as it is).
    """
    text = lesson_markdown(name)
    el.lesson_text.content = text
    el.lesson_text.visible = bool(text)
    if name == NONE:
        return False
    v = lesson_values(name)  # from the defaults: what a lesson shows must not depend on the lessons opened before
    h = el.inputs
    h["system"].value = v.system
    system = resolve(v)
    set_system(el, system, reset=True)
    assert system.Q is not None and system.R is not None and system.x0 is not None  # filled in __post_init__
    for s, x in zip(
        el.q_sliders + el.r_sliders, log_from_weights(np.diag(system.Q)) + log_from_weights(np.diag(system.R))
    ):
        s.value = x  # type: ignore[misc]  # viser's ``value`` setter is not seen (not next to its getter)
    for c in CONTROLS:
        if c.name in ("lesson", "system", "a_text", "b_text", "axes", "presenter"):  # presenter: the room's choice
            continue
        value = getattr(v, c.name) if c.name != "x0" or v.x0 else ", ".join(f"{x:g}" for x in system.x0)
        if h[c.name].value != value:
            h[c.name].value = value
    show_weights(el)
    return True


def read_values(el: GuiElements) -> Values:
    """The current inputs as one immutable :class:`Values` (and inputs shown/locked to match)."""
    h = el.inputs
    h["fixed_range"].visible = h["range_mode"].value == "fixed"
    h["rho"].disabled = bool(h["rho_auto"].value)
    return Values(
        **{c.name: c.convert(h[c.name].value) for c in CONTROLS},
        log_q=tuple(float(s.value) for s in el.q_sliders),
        log_r=tuple(float(s.value) for s in el.r_sliders),
    )


def panel_form(v: Values, system: LTISystem) -> Values:
    """What :func:`read_values` reads from a new panel made with ``v`` for ``system`` (its texts, x0 and weights
    filled in from the system): the settings a new tab computes, which the server's first view precomputes."""
    assert system.Q is not None and system.R is not None  # filled in __post_init__
    lq = v.log_q if len(v.log_q) == system.n else log_from_weights(np.diag(system.Q))
    lr = v.log_r if len(v.log_r) == system.m else log_from_weights(np.diag(system.R))
    fields = {c.name: c.convert(initial_value(c, v, system)) for c in CONTROLS}
    return Values(**fields, log_q=tuple(map(float, lq)), log_r=tuple(map(float, lr)))
