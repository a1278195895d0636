"""The legibility decision of the browser test (``tests/legibility.py``) on synthetic text boxes."""

from __future__ import annotations

from legibility import MIN_FIGURE_WIDTH, judge, summary


def _fig(*texts, box=(0, 0, 600, 400), name="error"):
    return {"name": name, "box": list(box), "texts": [dict(text=t, box=list(b), size=s) for t, b, s in texts]}


def test_apart_texts_of_a_readable_size_pass():
    fig = _fig(("0.5", (10, 380, 20, 12), 12), ("1", (60, 380, 10, 12), 12), ("b", (300, 390, 10, 10), 14))
    assert judge([fig], floor=10) == []


def test_overlapping_texts_are_one_problem_per_pair():
    fig = _fig(("title", (100, 10, 200, 20), 16), ("y axis", (90, 20, 20, 200), 14), ("far", (500, 300, 30, 12), 12))
    problems = judge([fig], floor=10)
    assert [(p.kind, p.what) for p in problems] == [("overlap", "'title' over 'y axis'")]


def test_touching_boxes_are_not_an_overlap():
    # one pixel shared (anti-aliasing, glyph bearings) is not text on text
    fig = _fig(("a", (10, 10, 20, 12), 12), ("b", (29, 10, 20, 12), 12))
    assert judge([fig], floor=10) == []
    fig = _fig(("a", (10, 10, 20, 12), 12), ("b", (27, 10, 20, 12), 12))
    assert [p.kind for p in judge([fig], floor=10)] == ["overlap"]


def test_text_under_the_floor_counts_and_the_floor_is_the_modes():
    fig = _fig(("note", (10, 10, 100, 9), 9), ("tick", (10, 380, 10, 12), 12))
    assert [p.kind for p in judge([fig], floor=10)] == ["small"]
    assert [p.what for p in judge([fig], floor=16)] == ["'note' at 9.0 px (< 16)", "'tick' at 12.0 px (< 16)"]


def test_a_narrow_figure_and_text_cut_off_at_its_edge():
    fig = _fig(("label", (230, 50, 40, 12), 12), box=(0, 0, 247, 154))
    kinds = [p.kind for p in judge([fig], floor=10)]
    assert kinds == ["narrow", "outside"]
    assert judge([fig], floor=10, min_width=None)[0].kind == "outside"
    assert judge([_fig(box=(0, 0, MIN_FIGURE_WIDTH, 300))], floor=10) == []


def test_summary_counts_kinds_and_figures():
    a = _fig(("x", (0, 0, 10, 10), 8), ("y", (2, 2, 10, 10), 8), name="a")
    b = _fig(("z", (0, 0, 10, 10), 9), name="b")
    assert summary(judge([a, b], floor=10)) == {"small": 3, "overlap": 1, "figures": 2}
