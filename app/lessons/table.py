"""Lessons a teacher opens in one click: ONE table (:data:`LESSONS`) of settings and what to look at, for linear
and nonlinear plants alike.

Each :class:`Lesson` sets panel values (fields of :class:`~app.settings.values.Values`) and shows 2-5 sentences.
Every claim a lesson's text makes is asserted on the numbers the dashboard computes for those settings
(``tests/dashboard/test_dashboard_lessons.py``, ``tests/dashboard/test_lessons_nonlinear.py``). A nonlinear
plant's lesson names every value whose default differs between the kinds (data size, MPC horizon and length,
training amplitude), so it shows the same numbers whatever the panel held before.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from app.settings.values import NO_LESSON, PAPER_SCALE, Values
from qsid_core import LETTER_QUANTIZER

from .bandwidth import bandwidth_lessons
from .start import START_LESSON

__all__ = [
    "Lesson",
    "LESSONS",
    "NONE",
    "BACK_LABEL",
    "lesson_names",
    "get_lesson",
    "lesson_values",
    "key_view",
]

#: The button that sets the panel back to the lesson's settings once they drifted.
BACK_LABEL = "↺ back to the lesson's settings"

#: The selector's entry for "no lesson" (the panel as it is).
NONE = NO_LESSON

#: The letter's settings (Section V): per-channel range, no guard band, subtractive dither, 200 x 1000, 50.
_LETTER = dict(
    dither=LETTER_QUANTIZER.dither,
    range_mode=LETTER_QUANTIZER.range_mode,
    guard=LETTER_QUANTIZER.guard,
    input_amplitude=1.0,
    **PAPER_SCALE,
)

#: Van der Pol and the pendulum at a data size the dashboard draws in about half a minute.
_NONLINEAR: dict[str, Any] = dict(
    lifting="poly:3",
    identification="LS + BCLS",
    trajectories=400,
    steps=100,
    realizations=10,
    horizon=20,
    mpc_steps=200,
    state_amplitude=2.0,
    dither="subtractive",
    range_mode="per-channel",
    guard=True,
)


@dataclass(frozen=True)
class Lesson:
    """One lesson: ``name`` (selector and ``--lesson``), a title, 2-5 sentences, panel value overrides, and
    ``plot``, the view (:data:`app.figures.registry.VIEWS`) it is about: opening the lesson brings its tab
    forward and shows that view first. ``moves``: the settings the text tells the person to change (following
    the text is not a drift from the lesson)."""

    name: str
    title: str
    text: str
    settings: dict
    plot: str = "error"
    #: what the text tells the person to change, one instruction per entry (fields set together): the panel
    #: after following one (or several) is not marked modified
    moves: tuple[dict, ...] = ()


LESSONS: tuple[Lesson, ...] = (
    Lesson(*START_LESSON),  # the guided start a new tab opens on (app.lessons.start)
    Lesson(
        "fig1",
        "The letter's Fig. 1 (dc motor)",
        "The letter's own settings and estimator, LS (200 runs × 1000 steps, 50 dither realizations, "
        "per-channel range, no guard band). Look at the error plot (show: Identification): Â and B̂ fall about "
        "0.3 decades per bit, like the grey dotted line, and the fitted slopes are read out next to the "
        "letter's −0.301 and −0.322: finite data, O(ε). Theorem 1's line is faded: the motor angle is an "
        "integrator. Move b to 2, 4 and 6: in the 3-D scene the closed loops (blue) close in on the "
        "true-model loop (black).",
        dict(system="dc-motor", bits=2, identification="LS", **_LETTER),
    ),
    Lesson(
        "fig2",
        "The letter's Fig. 2 (Boeing 747)",
        "The letter's settings and estimator, LS, on the Boeing 747. Look at the error plot (show: "
        "Identification): for b = 2..6 the error of Â falls about 0.55 decades per bit on Theorem 1's dashed line (its "
        "O(ε²) bias), from b = 8 on about 0.3 (finite data, O(ε)). B̂ is not on its line: the range (the "
        "data's min/max, no guard band) clips samples near the extremes, which moves B̂ by more than its "
        "fluctuation (the plot's note and the summary give the numbers). In the cost plot (show: Control) "
        "the identified models' MPC cost is within 0.01 % of the true model's (dashed) from b = 8 on.",
        dict(system="boeing747", bits=8, identification="LS", **_LETTER),
    ),
    Lesson(
        "theorem1",
        "Theorem 1 in action",
        "Boeing 747 (stable, so Ψ Ψᵀ/T converges), one shared range with guard band, the letter's data "
        "size; look at the error plot (show: Identification). Where the summary says every hypothesis holds "
        "(coarse b), the LS error of Â sits on the dashed Theorem 1 line (within 10 %): the O(ε²) bias. At "
        "fine b the line is faded: the O(ε) finite-data fluctuation dominates.",
        dict(
            system="boeing747",
            bits=3,
            identification="LS",
            range_mode="shared",
            guard=True,
            dither="subtractive",
            input_amplitude=1.0,
            **PAPER_SCALE,
        ),
    ),
    Lesson(
        "dither",
        "Why dither",
        "A coarse fixed range [-20, 20] at b = 3 (Boeing 747), error plot (show: Identification). With "
        "subtractive dither the noise is known (ε²/12, independent of the signal), so BCLS removes its bias: "
        "the BCLS error of Â is below 0.05 while LS is above 0.7; switch dither to 'none' and BCLS's noise "
        "model fails at b = 3 too (a red cross there; the crosses already shown mark clipping), its error above "
        "0.5. Move b to 12: LS and BCLS level off near 2e-4, and the plot's note names the cause: "
        "the range ±20 clips 0.05 % of the samples, and that, not the data length, sets this floor. Type the "
        "range -40, 40 and the error keeps falling.",
        dict(
            system="boeing747",
            bits=3,
            identification="LS + BCLS",
            range_mode="fixed",
            fixed_range="-20, 20",
            guard=False,
            dither="subtractive",
            input_amplitude=1.0,
            trajectories=200,
            steps=1000,
            realizations=5,
        ),
        moves=({"dither": "none"}, {"fixed_range": "-40, 40"}),
    ),
    Lesson(
        "one-cell",
        "Plain quantization fails, dither rescues it",
        "Boeing 747, one fixed range [-40, 40] at b = 4: cells 5 wide, so the inputs (|u| ≤ 1) stay in the two "
        "cells next to 0 and plain quantization keeps only their sign. Look at the quantizer plot (show: "
        "Quantizer, channel u: elevator): without dither the error is a deterministic function of u (a piece of the "
        "sawtooth), so the data say almost nothing about u, and LS and BCLS both miss Â and B̂ by more than "
        "60 % (error plot, show: Identification). Switch dither to 'subtractive': the error becomes a uniform "
        "band independent of u, and BCLS recovers Â and B̂ to within 5 %.",
        dict(
            system="boeing747",
            bits=4,
            identification="LS + BCLS",
            range_mode="fixed",
            fixed_range="-40, 40",
            guard=False,
            dither="none",
            input_amplitude=1.0,
            trajectories=200,
            steps=1000,
            realizations=5,
            view_channel=4,
        ),
        plot="quantizer",
        moves=({"dither": "subtractive"},),
    ),
    Lesson(
        "data-length",
        "Finite vs large data",
        "Boeing 747 with a small data set (50 runs × 200 steps). The summary flags 'finite data' from a "
        "coarser b on than at the letter's size, and Theorem 1's line is faded there; at b = 16 the "
        "measured error is far above the line (error plot, show: Identification). Press 'Paper scale' "
        "(200 × 1000): the line holds down to finer b. In show: Data length, its button draws the error against "
        "the data size.",
        dict(
            system="boeing747",
            bits=6,
            identification="LS",
            range_mode="per-channel",
            guard=True,
            dither="subtractive",
            input_amplitude=1.0,
            trajectories=50,
            steps=200,
            realizations=20,
        ),
        moves=(dict(PAPER_SCALE),),
    ),
    Lesson(
        "saturation",
        "Actuator saturation",
        "A large start x0 = (5, 5, 0, 0) and a small input bound 0.2 on the Boeing 747; look at the time "
        "series (show: Control): the inputs sit on ±0.2 for many steps, and the summary counts them. The loops "
        "still converge: ‖x_T‖ ends well below ‖x0‖.",
        dict(
            system="boeing747",
            bits=8,
            identification="LS",
            x0="5, 5, 0, 0",
            u_max=0.2,
            mpc_steps=100,
            guard=True,
            dither="subtractive",
            range_mode="per-channel",
            input_amplitude=1.0,
            trajectories=50,
            steps=200,
            realizations=20,
        ),
        plot="timeseries",
    ),
    Lesson(
        "bits-needed",
        "How many bits does the MPC need?",
        "The Boeing 747 at the letter's data size, LS, b = 2; look at the bits plot (show: Control). At b = 2 "
        "most loops never settle on the true plant (the summary counts them: the spectral radius of A − BK̂ "
        "is above 1), although none fails outright. The plot's title gives three answers: b_observed, from "
        "which on 95 % of the loops converge at a cost within 1 % of the true model's; b_robust, from which the "
        "small-gain certificate holds (for the model the title names); and b_letter, from which the letter's "
        "bound says anything. Why b = 1 settles more loops than b = 2: the 1-bit model is nearly empty, so its "
        "MPC barely acts and the stable Boeing settles on its own, while b = 2's half-right model acts harder, "
        "and wrongly.",
        dict(
            system="boeing747",
            bits=2,
            identification="LS",
            guard=True,
            dither="subtractive",
            range_mode="per-channel",
            input_amplitude=1.0,
            **PAPER_SCALE,
        ),
        plot="bits",
    ),
    Lesson(
        "tracking",
        "Bits and tracking",
        "The Boeing 747 tracks a sine on its speed u (reference sine:u:1:40, seen over the MPC's horizon); "
        "look at the residual plot (show: Control) and the time series. At b = 2 the tracking error (dotted) "
        "is more than twice the true model's, from b = 4 on it is within 5 % of it: the bits the model needs "
        "for tracking are few. The reference is drawn dashed in the time series and in the 3-D view.",
        dict(
            system="boeing747",
            bits=2,
            identification="LS",
            reference="sine:u:1:40",
            guard=True,
            dither="subtractive",
            range_mode="per-channel",
            input_amplitude=1.0,
            trajectories=200,
            steps=1000,
            realizations=20,
        ),
        plot="residual",
    ),
    Lesson(
        "feedback",
        "Quantized feedback: the floor",
        "Now the MPC measures the Boeing's state through a 4-bit quantizer (subtractive dither over the "
        "training range); look at the residual plot (show: Control). The loops keep a steady-state error of "
        "about 0.8: from b = 8 on it no longer falls with b and equals the true model's within 1 %, so the "
        "floor is the measurement, not the model, and the letter's δ (model error only) does not cover it. "
        "Set feedback bits to 8: the floor falls more than 4× (about half per bit). b = 1 lies below the floor "
        "because its nearly empty model barely acts (inputs ~10× smaller than the true model's), so it feeds "
        "little of the measurement's quantization error back into the plant.",
        dict(
            system="boeing747",
            bits=12,
            identification="LS",
            feedback_bits=4,
            guard=True,
            dither="subtractive",
            range_mode="per-channel",
            input_amplitude=1.0,
            trajectories=200,
            steps=1000,
            realizations=10,
        ),
        plot="residual",
        moves=({"feedback_bits": 8},),
    ),
    Lesson(
        "bound",
        "The ultimate bound",
        "Two bounds in the bound plot (show: Control): the letter's δ(ε) (green, from Theorem 1's T → ∞ model "
        "errors) and the a-posteriori δ (purple, from each realization's own model error): with finite data "
        "the a-posteriori δ is the larger one at every b. Both bound ‖x_t‖ only as t → ∞; the closed loops "
        "end below both. The summary's 'bound lesson' line reads how loose each δ is at the current b "
        "(against the measured ‖x_T‖), whether δ < ρ (else the proof gives no bound) and whether δ < ‖x0‖.",
        dict(
            system="dc-motor",
            bits=8,
            identification="LS",
            guard=True,
            dither="subtractive",
            range_mode="per-channel",
            input_amplitude=1.0,
            trajectories=50,
            steps=200,
            realizations=20,
        ),
        plot="bound",
    ),
    # nonlinear plants: Koopman/EDMD from quantized data
    Lesson(
        "koopman",
        "Koopman/EDMD from quantized data (Van der Pol)",
        "Van der Pol lifted by every monomial up to degree 3, 400 runs × 100 steps, 10 realizations; look at "
        "the error plot (show: Nonlinear). For b = 2..7 LS's error of [A_z, B_z] sits on its large-data limit "
        "(dashed, within 5 %): a quantization bias that more data do not remove, while BCLS, which de-biases "
        "every monomial exactly under subtractive dither, is 15 to 40 times lower for b = 3..6 (at the CLI's "
        "full scale, 2000 × 100, about 50 times at b = 3). From b = 11 on both agree within 10 %: the "
        "finite-data spread dominates. In 3-D: the plant's own flow (green, u = 0) from a grid of starts, each but "
        "the one at the origin winding onto the limit cycle, and the Koopman MPC loops at b = 3.",
        dict(system="van-der-pol", bits=3, **_NONLINEAR),
        "koopman-error",
    ),
    Lesson(
        "bias-variance",
        "Bias against variance: the pendulum at b = 2",
        "The pendulum at b = 2 (poly:3, 400 × 100, 10 realizations); look at the Koopman MPC outcomes "
        "(show: Nonlinear). BCLS's mean error of [A_z, B_z] is lower than LS's (below 1, LS above 1.4) but "
        "its spread is more than twice LS's: removing the bias of two-level data amplifies their noise. That "
        "variance costs control: LS's loops end within the convergence radius 0.1 in all 10 realizations, BCLS's "
        "in at most 8. None converges: each settles near, not at, the origin (bounded), as the unquantized EDMD's "
        "own loop does. Move b to 3: both end within the radius every time, and BCLS's error and prediction "
        "error are below LS's.",
        dict(system="pendulum", bits=2, **_NONLINEAR),
        "koopman-outcomes",
    ),
    *(Lesson(*row) for row in bandwidth_lessons(_NONLINEAR)),  # a link of limited bandwidth (app.lessons.bandwidth)
)


def lesson_names() -> tuple[str, ...]:
    """The selector's choices: :data:`NONE` and every lesson's name."""
    return (NONE,) + tuple(les.name for les in LESSONS)


def get_lesson(name: str) -> Lesson:
    """The lesson called ``name``.

    Raises
    ------
    KeyError
        With the valid names, if there is no such lesson.
    """
    for les in LESSONS:
        if les.name == name:
            return les
    raise KeyError(f"unknown lesson {name!r}; choose one of {', '.join(les.name for les in LESSONS)}")


def lesson_values(name: str, base: Values | None = None) -> Values:
    """The panel values of lesson ``name`` (``base`` with the lesson's overrides; x0 = the system's unless set)."""
    les = get_lesson(name)
    base = base or Values()
    kw = dict(les.settings)
    kw.setdefault("x0", "")
    return base.replace(log_q=(), log_r=(), a_text="", b_text="", lesson=name, **kw)


def key_view(name: str) -> str:
    """The view lesson ``name`` is about (the error plot without a lesson)."""
    return get_lesson(name).plot if name in lesson_names()[1:] else "error"
