"""Is every plot of the page legible? Boxes measured in the browser (:data:`TEXT_BOXES`), judged here.

The browser part is one JavaScript function that returns, for every plotly figure drawn on the page (visible,
not in a hidden tab), its box and the box, font size and text of each SVG text element in it (tick labels,
axis titles, titles, legend entries, annotations; the hover layer is left out). :func:`judge` decides in
Python, so the decision is unit-tested on synthetic boxes (``tests/dashboard/test_legibility_check.py``):

* two texts of one figure overlap (their boxes intersect by more than :data:`OVERLAP_PX` in both directions);
* a text is smaller than the floor (10 px; 16 px in presenter mode);
* a text lies (partly) outside its figure (cut off);
* a figure is narrower than :data:`MIN_FIGURE_WIDTH` (a phone's plot must still be readable).

Not a test module itself (pytest collects nothing here).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["TEXT_BOXES", "Problem", "judge", "summary", "NORMAL_FLOOR", "PRESENTER_FLOOR", "MIN_FIGURE_WIDTH"]

#: Smallest text (px) in normal mode and in presenter mode.
NORMAL_FLOOR, PRESENTER_FLOOR = 10.0, 16.0
#: Narrowest figure (px) that is still readable (a phone's full-width plot is ~360 px).
MIN_FIGURE_WIDTH = 340.0
#: Two boxes that share less than this (px) in x or in y merely touch (anti-aliasing, glyph bearings).
OVERLAP_PX = 1.5
#: A text may stick out of its figure by this much (px) before it counts as cut off.
OUTSIDE_PX = 2.0

#: JavaScript: ``[{name, box: [x, y, w, h], texts: [{text, box, size}]}]`` for every visible plotly figure.
#: ``name`` is the figure's title (or its first text). A text's size is the smallest font size of the element
#: and of its ``tspan`` children (plotly writes an HTML ``font-size`` span as a styled tspan).
TEXT_BOXES = """() => {
  const out = [];
  for (const gd of document.querySelectorAll('.js-plotly-plot')) {
    if (gd.offsetParent === null) continue;
    const r = gd.getBoundingClientRect();
    if (r.width === 0 || r.height === 0) continue;
    const texts = [];
    for (const e of gd.querySelectorAll('.main-svg text')) {
      if (e.closest('.hoverlayer')) continue;
      const t = e.textContent.trim();
      if (!t) continue;
      const s = getComputedStyle(e);
      if (s.display === 'none' || s.visibility === 'hidden' || parseFloat(s.opacity) === 0) continue;
      const b = e.getBoundingClientRect();
      if (b.width === 0 || b.height === 0) continue;
      let size = parseFloat(s.fontSize);
      for (const sp of e.querySelectorAll('tspan')) {
        if (sp.textContent.trim()) size = Math.min(size, parseFloat(getComputedStyle(sp).fontSize));
      }
      texts.push({text: t.slice(0, 80), box: [b.left, b.top, b.width, b.height], size: size,
                  cls: e.getAttribute('class') || ''});
    }
    const title = gd.querySelector('.gtitle');
    const name = (title && title.textContent.trim()) || (texts.length ? texts[0].text : '?');
    out.push({name: name.slice(0, 60), box: [r.left, r.top, r.width, r.height], texts: texts});
  }
  return out;
}"""


@dataclass(frozen=True)
class Problem:
    """One legibility problem: ``kind`` ('overlap', 'small', 'outside', 'narrow'), the figure, and what."""

    kind: str
    figure: str
    what: str

    def __str__(self) -> str:
        return f"{self.kind}: [{self.figure}] {self.what}"


def _intersection(a, b) -> tuple[float, float]:
    """Width and height (px) shared by boxes ``a`` and ``b`` (``[x, y, w, h]``; ≤ 0 when apart)."""
    w = min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0])
    h = min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1])
    return w, h


def judge(figures: list, floor: float, min_width: float | None = MIN_FIGURE_WIDTH) -> list[Problem]:
    """Every legibility problem of ``figures`` (what :data:`TEXT_BOXES` returned).

    Parameters
    ----------
    figures : list of dict
        ``{"name": str, "box": [x, y, w, h], "texts": [{"text": str, "box": [x, y, w, h], "size": float}]}``.
    floor : float
        Smallest allowed font size (px).
    min_width : float or None
        Narrowest allowed figure (px); None: not checked.

    Returns
    -------
    list of Problem
        Empty when every figure is legible.
    """
    out: list[Problem] = []
    for fig in figures:
        name = fig["name"]
        fb = fig["box"]
        if min_width is not None and fb[2] < min_width:
            out.append(Problem("narrow", name, f"drawn {fb[2]:.0f} × {fb[3]:.0f} px (< {min_width:.0f} px wide)"))
        texts = fig["texts"]
        for t in texts:
            if t["size"] < floor:
                out.append(Problem("small", name, f"{t['text']!r} at {t['size']:.1f} px (< {floor:g})"))
            w, h = _intersection(t["box"], fb)
            if w < t["box"][2] - OUTSIDE_PX or h < t["box"][3] - OUTSIDE_PX:
                out.append(Problem("outside", name, f"{t['text']!r} cut off at the figure's edge"))
        for i, a in enumerate(texts):
            for b in texts[i + 1 :]:
                w, h = _intersection(a["box"], b["box"])
                if w > OVERLAP_PX and h > OVERLAP_PX:
                    out.append(Problem("overlap", name, f"{a['text']!r} over {b['text']!r}"))
    return out


def summary(problems: list[Problem]) -> dict:
    """Counts per kind, and how many figures have at least one problem: ``{kind: n, "figures": n}``."""
    counts: dict = {}
    for p in problems:
        counts[p.kind] = counts.get(p.kind, 0) + 1
    counts["figures"] = len({p.figure for p in problems if p.kind != "none"})
    return counts
