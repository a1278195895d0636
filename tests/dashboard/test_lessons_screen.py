"""Lesson text against the screen (fast, no computation): what a lesson tells the person to click exists under
that name, every number it quotes is one of its settings or a claim a lesson test computes, and the "modified"
mark follows every drift its claims depend on but not the changes its text asks for."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from app.figures import registry
from app.figures.quantizer import channel_names
from app.lessons.drift import lesson_drift, lesson_markdown, lesson_panel
from app.lessons.table import LESSONS, get_lesson
from app.settings.values import resolve_system

HERE = Path(__file__).parent

#: The "show" dropdown's entries (the plots panel: app.dashboard.viewpanel), linear and nonlinear plants'.
SHOW = registry.TABS + registry.KOOPMAN_TABS
#: How a lesson names a view -> the view (app.figures.registry).
VIEW_WORDS = {
    "error plot": "error",
    "cost plot": "cost",
    "bits plot": "bits",
    "bound plot": "bound",
    "residual plot": "residual",
    "quantizer plot": "quantizer",
    "time series": "timeseries",
}
#: The same for a nonlinear plant's lessons (their own views).
KOOPMAN_WORDS = {"error plot": "koopman-error", "Koopman MPC outcomes": "koopman-outcomes"}
_SHOWN = re.compile(r"show: ([A-Z][a-z]+(?: [a-z]+)?)")
_VIEW_SHOWN = re.compile(r"(" + "|".join(VIEW_WORDS | KOOPMAN_WORDS) + r")(?: \(|, )show: ([A-Z][a-z]+(?: length)?)")

#: Numbers in a lesson's text that are neither a setting nor a claim: names (Theorem 1, Boeing 747, Fig. 1, x0)
#: and the uniform noise's variance ε²/12.
_NAMES = re.compile(
    r"arXiv 2503\.19102|https://arxiv\.org/abs/2503\.19102|3-D|Theorem 1|Boeing 747|Fig\. \d|x0|x_T|ε²/12|ε²|A − BK̂|\[A_z, B_z\]"
)
_NUMBER = re.compile(r"(?<![\w.])[−-]?\d+(?:\.\d+)?(?:e-?\d+)?")

#: Every number a lesson's text claims about its results -> the test that computes and asserts it at the lesson's
#: settings (tests/dashboard/test_dashboard_lessons.py, test_lessons_control.py, test_lessons_nonlinear.py).
CLAIMS: dict[str, dict[str, tuple[str, ...]]] = {
    "fig1": {
        "test_fig1_letter_settings_0p3_per_bit_faded_theorem_loops_close_in": ("0.3", "4", "6"),
        "test_the_letters_slopes_are_printed_for_its_dc_motor_only": ("−0.301", "−0.322"),
    },
    "fig2": {"test_fig2_boeing_cost_approaches_true_cost": ("2", "6", "0.55", "8", "0.3", "0.01")},
    "theorem1": {"test_theorem1_ls_on_the_line_where_hypotheses_hold": ("10",)},
    "dither": {
        "test_why_dither_bcls_removes_known_noise_only_with_dither": ("0.05", "0.7", "0.5"),
        "test_dither_lesson_at_b12_names_clipping": ("12", "2e-4", "0.05"),
    },
    "one-cell": {"test_one_cell_lesson_plain_fails_dither_rescues": ("5", "0", "60")},
    "data-length": {"test_data_length_more_finite_data_flags_at_the_small_size": ("16",)},
    "saturation": {"test_saturation_many_saturated_steps_and_loops_converge": ()},
    "bits-needed": {"test_bits_needed_explains_why_b1_settles_and_b2_does_not": ("1",)},
    "tracking": {"test_tracking_lesson": ("2", "4", "5")},
    "feedback": {
        "test_feedback_lesson": ("0.8", "8", "1", "4"),
        "test_feedback_lesson_explains_b1_below_the_floor": ("1", "10"),
    },
    "bound": {},
    "koopman": {
        "test_koopman_ls_on_its_limit_bcls_15_to_40_times_lower_and_both_agree_at_fine_b": (
            "2",
            "7",
            "5",
            "15",
            "40",
            "6",
            "11",
            "10",
        ),
        "test_koopman_full_scale_ratio_is_about_50": ("2000", "100", "50"),
    },
    "bias-variance": {
        "test_bias_variance_bcls_lower_mean_larger_spread_fewer_loops_within_the_radius_at_b2": (
            "1",
            "1.4",
            "10",
            "8",
            "0.1",
        ),
        "test_bias_variance_at_b3_both_end_within_the_radius_and_bcls_wins": ("3",),
    },
    "start": {"test_every_claim_of_the_start_text_holds_at_the_default_settings": ("0.3", "5")},
    "bandwidth": {
        "test_boeing_noise_free_finer_words_win_noisy_knee_near_6_loops_all_stabilize": ("3333", "208", "16", "12"),
    },
    "bandwidth-koopman": {
        "test_van_der_pol_finer_words_win_loops_bounded_within_radius_from_b3": ("1666", "104", "16")
    },
}
_TEST_FILES = (
    "test_dashboard_lessons.py",
    "test_lessons_control.py",
    "test_lessons_nonlinear.py",
    "test_dashboard_truth.py",
    "test_dashboard_start.py",
    "test_lesson_bandwidth.py",
)


def _numbers(text: str) -> list[str]:
    return _NUMBER.findall(_NAMES.sub(" ", text))


def _setting_numbers(name: str) -> set[str]:
    """Every number the lesson's settings (and the changes its text asks for) hold, also as percent."""
    les, v = get_lesson(name), lesson_panel(name)
    out: set[str] = set()
    for field in v.__dataclass_fields__:
        x = getattr(v, field)
        if isinstance(x, bool):
            continue
        if isinstance(x, (int, float)):
            out |= {f"{x:g}", f"{100 * x:g}"}
        elif isinstance(x, str):
            out |= set(_NUMBER.findall(x))
    for move in les.moves:
        out |= {n for x in move.values() for n in _NUMBER.findall(str(x))}
    return out | {n.replace("-", "−") for n in out}


@pytest.mark.parametrize("les", LESSONS, ids=lambda les: les.name)
def test_a_lessons_text_names_the_show_dropdowns_entries(les):
    """ "the Identification tab", "(Quantizer tab, channel u)", "Nonlinear group" named nothing to click: the
    plots are picked in the plots panel's "show" dropdown."""
    assert not re.search(r"\btab\b|\bgroup\b", les.text), les.text
    shown = _SHOWN.findall(les.text)
    assert shown and set(shown) <= set(SHOW), (shown, SHOW)
    key = next(v.tab for v in registry.ALL_VIEWS if v.name == les.plot)
    assert key in shown  # the lesson's own view is where the text sends you
    words_of = KOOPMAN_WORDS if les.plot.startswith("koopman-") else VIEW_WORDS
    for words, group in _VIEW_SHOWN.findall(les.text):  # "the error plot (show: Identification)": it is there
        assert next(v.tab for v in registry.ALL_VIEWS if v.name == words_of[words]) == group, (words, group)


def test_the_channel_a_lesson_names_is_the_channel_it_shows():
    for les in LESSONS:
        for named in re.findall(r"channel ([^,()]+: [^)]+)\)", les.text):
            v = lesson_panel(les.name)
            assert channel_names(resolve_system(v).system)[v.view_channel] == named, les.name


@pytest.mark.parametrize("les", LESSONS, ids=lambda les: les.name)
def test_every_number_in_a_lessons_text_is_a_setting_or_a_tested_claim(les):
    """A number in the text is either one of the lesson's settings (as the panel shows it) or a claim about its
    results that a lesson test computes at those settings (then the "modified" mark covers any other panel)."""
    claims = CLAIMS[les.name]
    sources = "".join((HERE / f).read_text() for f in _TEST_FILES)
    for test in claims:
        assert f"def {test}(" in sources, test
    known = _setting_numbers(les.name) | {n for ns in claims.values() for n in ns}
    loose = [n for n in _numbers(les.title + " " + les.text) if n not in known]
    assert not loose, (les.name, loose)


def test_no_text_quotes_a_number_shown_nowhere():
    """bits-needed quoted ‖K̂‖ ≈ 0.24 / 0.66 / 1.08 (on no plot, in no summary) and b_observed 4, b_robust 5,
    b_letter 9 (the plot's title says them, and they change with the panel): now it points at the title."""
    text = get_lesson("bits-needed").text
    assert "‖K̂‖" not in text and "0.24" not in text and "b_observed, 4" not in text
    assert "The plot's title gives three answers" in text and "for the model the title names" in text
    assert "Theorem 1's model (b_robust" not in text  # the title names the model the certificate holds for


@pytest.mark.parametrize("les", LESSONS, ids=lambda les: les.name)
def test_following_the_text_is_no_drift_and_any_other_change_is(les):
    """The mark ("✎ Modified from the lesson") for any setting the lesson's numbers depend on (seeds, per-channel
    bits, Q/R weights ...), not for b, the drawing (presenter, channel) or a change the text asks for."""
    v = lesson_panel(les.name)
    assert lesson_drift(les.name, v) == ()
    assert lesson_drift(les.name, v.replace(bits=v.bits % 16 + 1, presenter=True, view_channel=0)) == ()
    for move in les.moves:  # what the text says to do
        assert lesson_drift(les.name, v.replace(**move)) == (), move
    if len(les.moves) > 1:
        together = {k: x for m in les.moves for k, x in m.items()}
        assert lesson_drift(les.name, v.replace(**together)) == ()
    for field, value in (
        ("data_seed", v.data_seed + 5),
        ("dither_seed", v.dither_seed + 1),
        ("loop_seed", v.loop_seed + 1),
        ("input_bits", "2"),
        ("log_q", (2.0,) + v.log_q[1:]),
        ("horizon", v.horizon + 1),
    ):
        drift = lesson_drift(les.name, v.replace(**{field: value}))
        assert drift == (field,), (field, drift)
    assert "✎ **Modified from the lesson** (data seed)" in lesson_markdown(les.name, ("data_seed",))


def test_the_dither_lessons_own_instruction_is_no_drift_but_half_of_paper_scale_is():
    v = lesson_panel("dither")
    assert lesson_drift("dither", v.replace(dither="none", fixed_range="-40,40", bits=12)) == ()
    assert lesson_drift("dither", v.replace(dither="tpdf")) == ("dither",)
    d = lesson_panel("data-length")
    assert lesson_drift("data-length", d.replace(trajectories=200, steps=1000, realizations=50)) == ()
    assert lesson_drift("data-length", d.replace(trajectories=200)) == ("trajectories",)  # not the button
