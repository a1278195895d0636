"""The control panel of one browser tab, built from ONE table of control specs (:data:`CONTROLS`).

Like viser's SMPL example (``examples/04_demos/03_smpl_visualizer.py``),
:func:`make_gui_elements` builds every handle into one :class:`GuiElements`
dataclass; every input's callback only marks the tab dirty (``on_change``); the
tab's one worker loop (:mod:`app.dashboard.session`) reads :func:`read_values`
and redraws. Choices and ranges come from the engine (via
:mod:`app.dashboard.settings`); the slider ranges here are the panel's own.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from app.figures.phase_scene import axes_options
from qsid_core import LTISystem
from qsid_core.quantization import DITHERS, RANGE_MODES

from .flow import inline

if TYPE_CHECKING:
    import viser
from .lessons import NONE, lesson_markdown, lesson_names, lesson_values
from .settings import (
    ALL_BITS,
    IDENT_CHOICES,
    INTERACTIVE,
    LOG_MAX,
    LOG_MIN,
    PAPER_SCALE,
    SYSTEM_CHOICES,
    Values,
    format_weights,
    log_from_weights,
    matrix_text,
    weights_from_log,
)

__all__ = [
    "Control",
    "CONTROLS",
    "GuiElements",
    "make_gui_elements",
    "read_values",
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
MATRIX_HINT = "One row per line (or separate rows with ';'); numbers separated by spaces or commas."


@dataclass(frozen=True)
class Control:
    """One input of the panel; ``name`` is the :class:`~app.dashboard.settings.Values` field it sets.

    ``kind``: slider (lo, hi, step), dropdown (choices), text, checkbox, number (lo, step);
    ``tab``: panel tab ("" = above the tabs); ``folder``: optional folder inside the tab.
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


_R = "Dither realizations"
_V = "How many bits?"
_L = "Real loop"
#: Every input of the panel, in display order (tabs appear in order of first use).
CONTROLS: tuple[Control, ...] = (
    Control(
        "lesson",
        "dropdown",
        "lesson",
        choices=lesson_names(),
        hint="A lesson sets the controls and says what to look at (every claim is tested)",
    ),
    Control(
        "bits",
        "slider",
        "word length b",
        lo=ALL_BITS[0],
        hi=ALL_BITS[-1],
        step=1,
        convert=int,
        hint=f"Bits per sample of the quantizer ({ALL_BITS[0]}..{ALL_BITS[-1]}). "
        "Curves show every b; the 3-D view shows this one.",
    ),
    Control(
        "presenter",
        "checkbox",
        "presenter",
        convert=bool,
        hint="Lecture-hall layout: plot text 18 px, panel text 16 px, thick lines, a wide 3-D scene "
        "(both panels narrowed). Auto-play below steps b from 1 to 16.",
    ),
    Control(
        "system",
        "dropdown",
        "system",
        "System",
        choices=SYSTEM_CHOICES,
        hint="The true plant. 'custom': type A and B below.",
    ),
    Control("a_text", "text", "A", "System", hint=MATRIX_HINT),
    Control("b_text", "text", "B", "System", hint=MATRIX_HINT),
    Control("axes", "dropdown", "3-D axes", "System", hint="Which three states the phase portrait draws."),
    Control(
        "dither",
        "dropdown",
        "dither",
        "Quantizer",
        choices=DITHERS,
        hint="subtractive: x~ = Q(x + w) - w, w ~ U[-ε/2, ε/2]. tpdf: Q(x + w), w triangular on [-ε, ε], "
        "not subtracted (error variance ε²/4, known). rpdf: Q(x + w), w uniform, not subtracted "
        "(variance depends on the signal: BCLS does not apply). none: Q(x)",
    ),
    Control(
        "range_mode",
        "dropdown",
        "range",
        "Quantizer",
        choices=RANGE_MODES,
        hint="per-channel min/max, one shared range, or a fixed range typed below",
    ),
    Control(
        "fixed_range",
        "text",
        "fixed range",
        "Quantizer",
        hint="'lo, hi' for every channel, or one 'lo hi' row per channel (states, then inputs)",
    ),
    Control(
        "guard",
        "checkbox",
        "guard band",
        "Quantizer",
        convert=bool,
        hint="Widen the range by the dither's amplitude each side (ε/2; ε for tpdf): no overload",
    ),
    Control(
        "state_bits",
        "text",
        "state bits",
        "Quantizer",
        hint="Word length of the states: 'b' (the slider's b, as the letter), or one entry for all or one "
        "per state, each 'b', a number or 'exact', like 'b, b, 12, exact'",
    ),
    Control(
        "input_bits",
        "text",
        "input bits",
        "Quantizer",
        hint="Word length of the inputs: 'same' (= b, as the letter), 'exact' (inputs not quantized), "
        "one number for all inputs, or one per input like '8, exact'; b then sweeps the states",
    ),
    Control(
        "realizations",
        "slider",
        "realizations",
        "Quantizer",
        1,
        100,
        1,
        folder=_R,
        convert=int,
        hint=f"Independent dither draws per b (paper: {PAPER_SCALE['realizations']}, "
        f"interactive default: {INTERACTIVE['realizations']})",
    ),
    Control("dither_seed", "number", "dither seed", "Quantizer", 0, step=1, folder=_R, convert=int),
    Control(
        "trajectories",
        "slider",
        "trajectories",
        "Data",
        1,
        400,
        1,
        convert=int,
        hint=f"Training runs (paper: {PAPER_SCALE['trajectories']})",
    ),
    Control(
        "steps",
        "slider",
        "steps",
        "Data",
        10,
        2000,
        10,
        convert=int,
        hint=f"Steps per training run (paper: {PAPER_SCALE['steps']})",
    ),
    Control("data_seed", "number", "data seed", "Data", 0, step=1, convert=int),
    Control(
        "input_amplitude",
        "number",
        "input amplitude",
        "Data",
        1e-6,
        step=0.1,
        convert=float,
        hint="Training inputs u ~ U[-A, A] (the letter: A = 1). Small A: a small signal against the quantizer range",
    ),
    Control(
        "noise",
        "text",
        "sensor noise σ",
        "Data",
        hint="Gaussian noise added to the recorded states before quantization: one σ for every state or "
        "one per state (empty = none; seeded by the data seed)",
    ),
    Control(
        "identification",
        "dropdown",
        "estimator",
        "Identify",
        choices=tuple(IDENT_CHOICES),
        hint="LS: least squares on quantized data. BCLS: bias-compensated LS "
        "(subtracts the known noise T·diag(D): ε²/12 subtractive, ε²/4 tpdf dither).",
    ),
    Control(
        "noise_known",
        "checkbox",
        "sensor noise known to BCLS",
        "Identify",
        convert=bool,
        hint="BCLS adds σ² to D; unticked, BCLS corrects only the quantization noise it knows of",
    ),
    Control("horizon", "slider", "horizon", "MPC", 1, 50, 1, convert=int),
    Control("u_max", "slider", "input bound", "MPC", 0.05, 10.0, 0.05, convert=float, hint="|u_i| <= this bound"),
    Control("x0", "text", "x0", "MPC", hint="Initial state of the closed loop, one number per state"),
    Control("mpc_steps", "slider", "closed-loop steps", "MPC", 5, 300, 5, convert=int),
    Control(
        "x_ref",
        "text",
        "reference x_ref",
        "MPC",
        hint="Constant reference, one number per state (empty = regulate to 0). δ(ε) assumes x_ref = 0.",
    ),
    Control(
        "reference",
        "text",
        "reference r(t)",
        "MPC",
        hint="Time-varying reference with preview: step:STATE:AMP:TIME, sine:STATE:AMP:PERIOD or "
        "square:STATE:AMP:PERIOD (STATE a name or 1-based, times in samples); empty = constant x_ref",
    ),
    Control(
        "tracking",
        "dropdown",
        "tracking form",
        "MPC",
        choices=("letter", "offset-free"),
        hint="letter: cost u'Ru (a reference that is no equilibrium leaves an offset); offset-free: "
        "(u - u_ref)'R(u - u_ref) with u_ref = B^+(I - A^) r, the input that holds the model at r",
    ),
    Control(
        "x_max",
        "text",
        "state box x_max",
        "MPC",
        hint="|x_i| <= x_max_i over the horizon: one number for every state or one per state (empty = none)",
    ),
    Control(
        "qf",
        "text",
        "terminal weight Qf",
        "MPC",
        hint="'dare' (each model's stabilizing DARE solution, default), 'Q' (the stage weight) or a "
        "diagonal: one number for every state or one per state",
    ),
    Control(
        "terminal_box",
        "text",
        "terminal box",
        "MPC",
        hint="|x_N,i| <= X_i on the last predicted state: one number for every state or one per state (empty = none)",
    ),
    Control(
        "disturbance",
        "number",
        "disturbance σ",
        "MPC",
        0.0,
        step=0.005,
        folder=_L,
        convert=float,
        hint="Process noise added to the true plant in the closed loop (standard deviation; the same draws "
        "for every b, estimator and the true-model loop)",
    ),
    Control("disturbance_kind", "dropdown", "disturbance kind", "MPC", choices=("gaussian", "uniform"), folder=_L),
    Control(
        "feedback_bits",
        "slider",
        "feedback bits",
        "MPC",
        0,
        16,
        1,
        folder=_L,
        convert=int,
        hint="The MPC measures the state through this many bits per state (subtractive dither, the training "
        "data's range); 0 = exact state",
    ),
    Control(
        "feedback_noise",
        "number",
        "sensor noise σ",
        "MPC",
        0.0,
        step=0.005,
        folder=_L,
        convert=float,
        hint="Noise on the state the MPC measures (standard deviation)",
    ),
    Control("loop_seed", "number", "loop seed", "MPC", 0, step=1, folder=_L, convert=int),
    Control(
        "verify_steps",
        "number",
        "verdict steps",
        "MPC",
        0,
        step=500,
        folder=_V,
        convert=int,
        hint="At most this many extra closed-loop steps to decide whether a loop converges, stays bounded "
        "or diverges on the true plant (where the spectral radius alone does not decide)",
    ),
    Control(
        "target",
        "slider",
        "target stabilized",
        "MPC",
        0.5,
        1.0,
        0.01,
        folder=_V,
        convert=float,
        hint="b_observed: the smallest b from which on at least this share of the loops converge …",
    ),
    Control(
        "cost_gap",
        "number",
        "cost gap",
        "MPC",
        0.0,
        step=0.005,
        folder=_V,
        convert=float,
        hint="… and the mean closed-loop cost is within this relative gap of the true model's (0.01 = 1 %)",
    ),
    Control(
        "theta",
        "slider",
        "θ",
        "Theory",
        0.05,
        0.95,
        0.05,
        convert=float,
        hint="Share of the Lyapunov decrease used against the model error (ultimate bound δ(ε))",
    ),
    Control(
        "rho_auto",
        "checkbox",
        "ρ auto",
        "Theory",
        convert=bool,
        hint="ρ = sqrt(x0ᵀP x0 / λmin(P)), the smallest ball holding {V ≤ V(x0)} (engine default)",
    ),
    Control("rho", "number", "ρ", "Theory", 1e-6, step=0.1, convert=float),
    Control(
        "show_bound",
        "checkbox",
        "bound in 3-D",
        "Theory",
        convert=bool,
        hint="Draw the ultimate bounds as circles in the 3-D view (hide them to see the loops alone)",
    ),
)


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
    on_change: Callable[..., None]
    q_sliders: list[viser.GuiSliderHandle[float]] = field(default_factory=list)
    r_sliders: list[viser.GuiSliderHandle[float]] = field(default_factory=list)
    system_key: tuple[Any, ...] | None = None

    def __getitem__(self, name: str) -> Any:
        return self.inputs[name]


def _initial(c: Control, v: Values, system: LTISystem) -> Any:
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
    if c.kind == "number":
        return gui.add_number(c.label, value, min=c.lo, step=c.step, hint=c.hint)
    if c.kind == "checkbox":
        return gui.add_checkbox(c.label, value, hint=c.hint)
    if c.kind == "dropdown":
        choices: tuple[str, ...] = c.choices or tuple(axes_options(system.state_names))
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
        paper.on_click(lambda _: set_scale(handles, PAPER_SCALE))
        inter.on_click(lambda _: set_scale(handles, INTERACTIVE))
    elif name == "identification":
        gui.add_markdown(
            "LS is biased by the quantization noise (Theorem 1); BCLS removes that bias. "
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
        h = _add(gui, c, _initial(c, values, system), system, custom)
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
    tabs = gui.add_tab_group()
    for tab in dict.fromkeys(c.tab for c in CONTROLS if c.tab):
        with tabs.add_tab(tab):
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
    with gui.add_folder("Summary"):
        extra["summary"] = gui.add_markdown("")
    handles["fixed_range"].visible = values.range_mode == "fixed"
    handles["rho"].disabled = bool(values.rho_auto)
    handles["axes"].visible = len(axes_options(system.state_names)) > 1
    el = GuiElements(gui=gui, inputs=handles, on_change=on_change, **extra)
    set_system(el, system, values.log_q, values.log_r, reset=False)
    return el


def _system_note(name: str) -> str:
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
