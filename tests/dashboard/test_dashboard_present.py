"""Class-ready presenting and sharing (issue 38, part 5): plotly's options on every plot, the left panel's order in
presenter mode, and percent axes written without SI prefixes."""

from __future__ import annotations

import json

from app.figures.raw import PLOT_CONFIG, Wire, to_json


def test_every_plot_is_sent_without_a_cloud_upload(tab):
    """Every plot pushed (blank ones included) carries the config: no "Share chart…" / Chart Studio button."""
    assert PLOT_CONFIG["showSendToCloud"] is False and PLOT_CONFIG["showEditInChartStudio"] is False
    assert "sendDataToCloud" in PLOT_CONFIG["modeBarButtonsToRemove"]
    for name, h in tab.session.plots.items():
        sent = json.loads(h._plotly_json_str)
        assert sent["config"] == PLOT_CONFIG, name
    import plotly.graph_objects as go

    assert json.loads(Wire(go.Figure()).to_json())["config"] == PLOT_CONFIG  # plotly's own path too
    assert json.loads(to_json(go.Figure(layout=dict(title="t"))))["layout"]["title"]["text"] == "t"
    from app.frames.exports import figures_html

    page = figures_html({"error": go.Figure()}, "t", "c")  # the offline HTML export too
    assert '"showSendToCloud": false' in page and "sendDataToCloud" in page


def test_presenter_mode_puts_slider_play_and_switch_above_the_lesson_text(tab):
    tab.set(lesson="bound")
    s, c = tab.session, tab.controls
    before = float(c.lesson_text.order)
    assert float(c.lesson_text.order) < float(c["bits"].order)  # normal mode: the text first
    tab.set(presenter=True)
    p = s.presenter
    orders = [float(h.order) for h in (c["bits"], c.play, p.switch, c.lesson_text, s.mark.back, s.codes.line)]
    assert orders == sorted(orders), orders  # slider, auto-play, switch, then the text, then the view code
    assert p.switch.visible
    tab.set(presenter=False)
    assert float(c.lesson_text.order) == before and not p.switch.visible


def _axes(layout: dict):
    for key, ax in layout.items():
        if (key.startswith("xaxis") or key.startswith("yaxis")) and isinstance(ax, dict):
            yield key, ax


def test_percent_and_log_axes_never_print_si_prefixes(tab):
    """The cost gap's axis printed "1μ" (percent with an SI prefix): every log axis and every percent axis of
    every plot drawn writes its numbers as powers of ten (or plain), never with plotly's default SI prefixes."""
    tab.set(lesson="bound")  # the Control group's plots drawn, the bits plot among them
    seen = set()
    for name, h in tab.session.plots.items():
        layout = json.loads(h._plotly_json_str)["layout"]
        for key, ax in _axes(layout):
            title = str((ax.get("title") or {}).get("text", ""))
            percent = "%" in title or "%" in str(ax.get("tickformat", ""))
            if ax.get("type") == "log" or percent:
                seen.add((name, key, percent))
                assert ax.get("exponentformat") in ("power", "none") or ax.get("tickformat"), (name, key, title)
    assert ("bits", "yaxis2", True) in seen  # the cost gap's percent axis was among them


def test_notes_behind_the_hover_are_shown_on_a_projector_and_a_phone():
    """ "hover here: why" means nothing on a phone or a projector: there the note's sentences are its text."""
    from app.figures.presenter import HOVER_HERE, legible_figure, phone_figure, presenter_figure
    from app.figures.raw import figure

    sentences = "Theorem 1 faded: the motor angle is an integrator.<br>BCLS ✕: no dither."
    note = dict(text=f"Notes: Theorem 1 faded · BCLS ✕ {HOVER_HERE}", hovertext=sentences, x=0, y=1.0)
    note.update(xref="paper", yref="paper", yanchor="bottom", showarrow=False)
    fig = figure([dict(type="scatter", x=[1, 2], y=[1, 2])], dict(annotations=[note], title=dict(text="error")))
    for show in (presenter_figure, phone_figure):
        anns = show(fig).to_plotly_json()["layout"]["annotations"]
        texts = [a.get("text", "") for a in anns]
        assert any("integrator" in t and "no dither" in t for t in texts), texts
        assert not any(HOVER_HERE in t for t in texts) and not any(a.get("hovertext") for a in anns)
    kept = legible_figure(fig).to_plotly_json()["layout"]["annotations"]  # a laptop keeps the hover (one line)
    assert any(HOVER_HERE in a["text"] and a["hovertext"] == sentences for a in kept)
