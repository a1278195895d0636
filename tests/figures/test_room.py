"""A figure laid out for a known size (app/figures/room.py): panels stacked, room for every text, nothing cut.

What the browser measures (tests/system/test_dashboard_legibility.py) rests on these rules; here they are
checked on plain layouts, without a browser.
"""

from __future__ import annotations

import plotly.graph_objects as go
import pytest

from app.figures.presenter import PHONE_FONT, PHONE_WIDTH, PLOT_FONT, PRESENTER_SIZE, phone_figure, presenter_figure
from app.figures.room import CHAR, lay_out, wrap_text


def _side_by_side(title: str = "a title") -> tuple[dict, list]:
    """Two panels side by side with a title over each, as the error and data-length views draw them."""
    layout = dict(
        font=dict(size=12),
        title=dict(text=title),
        margin=dict(l=50, r=10, t=30, b=40),
        xaxis=dict(domain=[0.0, 0.44], anchor="y", title=dict(text="b")),
        xaxis2=dict(domain=[0.56, 1.0], anchor="y2", title=dict(text="b")),
        yaxis=dict(anchor="x", type="log"),
        yaxis2=dict(anchor="x2", type="log"),
        annotations=[
            dict(text="left", x=0.22, xanchor="center", xref="paper", y=1.0, yanchor="bottom", yref="paper"),
            dict(text="right", x=0.78, xanchor="center", xref="paper", y=1.0, yanchor="bottom", yref="paper"),
        ],
    )
    data = [
        dict(type="scatter", x=[1, 2], y=[1, 2], name="one", xaxis="x", yaxis="y"),
        dict(type="scatter", x=[1, 2], y=[1, 2], name="two", xaxis="x2", yaxis="y2"),
    ]
    return layout, data


def test_wrap_text_breaks_at_spaces_outside_tags():
    text = "one two three <span style='font-size:12px'>four five</span> six"
    out = wrap_text(text, 9)
    assert "<br>" in out and out.replace("<br>", " ") == text
    assert "<span style='font-size:12px'>" in out  # a tag is never broken
    assert wrap_text("short", 20) == "short"


def test_side_by_side_panels_are_stacked_each_across_the_figure_with_their_titles():
    layout, data = _side_by_side()
    h = lay_out(layout, data, 400.0)
    assert layout["xaxis"]["domain"] == layout["xaxis2"]["domain"] == [0.0, 1.0]
    top, bottom = layout["yaxis"]["domain"], layout["yaxis2"]["domain"]
    assert bottom[1] < top[0]  # the first panel above the second, apart
    left, right = layout["annotations"][:2]
    assert (left["x"], left["y"]) == (0.5, top[1]) and (right["x"], right["y"]) == (0.5, bottom[1])
    # the gap between the rows holds the upper row's tick labels, its axis title and the lower row's title
    paper = h - layout["margin"]["t"] - layout["margin"]["b"]
    assert (top[0] - bottom[1]) * paper >= 3 * 12
    assert layout["height"] == round(h) and h > 2 * 0.42 * 400 * 0.9


def test_the_title_becomes_a_wrapped_block_and_the_top_margin_holds_it():
    layout, data = _side_by_side("word " * 60)
    lay_out(layout, data, 300.0, 300.0)
    assert layout["title"]["text"] == ""
    block = layout["annotations"][-1]
    lines = block["text"].split("<br>")
    assert len(lines) > 1 and all(len(line) * CHAR * 12 <= 300 for line in lines)
    assert layout["margin"]["t"] >= len(lines) * 12 * 1.3 + block["yshift"]


def test_a_fixed_height_grows_only_for_rows_too_low():
    layout, data = _side_by_side()
    assert lay_out(layout, data, 1000.0, 600.0) == 600.0
    layout, data = _side_by_side()
    assert lay_out(layout, data, 1000.0, 300.0, min_row=150.0) > 300.0


def test_a_long_legend_gets_rows_at_the_foot():
    layout, data = _side_by_side()
    few = lay_out(layout, data, 360.0)
    layout2, data2 = _side_by_side()
    data2 += [dict(type="scatter", x=[1], y=[1], name=f"a long legend entry {i}") for i in range(8)]
    many = lay_out(layout2, data2, 360.0)
    assert layout2["margin"]["b"] > layout["margin"]["b"] + 3 * 12 and many > few
    assert layout2["legend"]["yref"] == "container" and layout2["legend"]["orientation"] == "h"


@pytest.mark.parametrize("style,floor", [(presenter_figure, PLOT_FONT), (phone_figure, PHONE_FONT)])
def test_the_presenter_and_phone_styles_stack_panels_and_keep_their_text_floor(style, floor):
    layout, data = _side_by_side()
    out = style(go.Figure(dict(data=data, layout=layout)))
    lay = out.layout
    assert tuple(lay.xaxis.domain) == (0.0, 1.0) and lay.yaxis2.domain[1] < lay.yaxis.domain[0]
    assert lay.font.size >= floor and all(a.font.size is None or a.font.size >= floor for a in lay.annotations)
    if style is phone_figure:
        assert lay.height > PHONE_WIDTH  # as high as its stacked panels need (the plot's aspect follows)
    else:
        assert lay.height == PRESENTER_SIZE[1]


def test_a_sentence_broken_for_a_laptop_is_joined_before_it_is_wrapped_again():
    laptop = (
        "LS: stabilizes at least 95 % of the loops, with a cost within 1 %,<br>from b = 4 on.<br>BCLS: from b = 3 on."
    )
    out = wrap_text(laptop, 200).split("<br>")
    assert out == [
        "LS: stabilizes at least 95 % of the loops, with a cost within 1 %, from b = 4 on.",
        "BCLS: from b = 3 on.",
    ]
    kept = "steady-state error (last half of the loop)<br>causes besides the model: noise"
    assert wrap_text(kept, 200) == kept  # a line of its own, not the rest of a sentence


def _rows_px(layout: dict) -> list[float]:
    paper = layout["height"] - layout["margin"]["t"] - layout["margin"]["b"]
    return [(layout[k]["domain"][1] - layout[k]["domain"][0]) * paper for k in ("yaxis", "yaxis2")]


def test_notes_shown_above_the_plot_add_to_the_height_and_leave_the_panels_their_room():
    """Presenter mode shows a note's sentences (no hover on a projector): three lines of notes squashed the two
    error panels to 81 px each at 1366 x 768, so the notes now add to the height asked for."""
    bare, data = _side_by_side()
    lay_out(bare, data, 1000.0, 600.0)
    noted, data2 = _side_by_side()
    noted["annotations"].append(
        dict(text="Notes: " + "a sentence of a note " * 30, x=0, xanchor="left", xref="paper", y=1.0)
        | dict(yanchor="bottom", yref="paper")
    )
    h = lay_out(noted, data2, 1000.0, 600.0)
    assert h > 600.0 + 2 * 12  # grown by the notes' lines
    for with_notes, without in zip(_rows_px(noted), _rows_px(bare), strict=True):
        assert with_notes >= 0.98 * without, (with_notes, without)
