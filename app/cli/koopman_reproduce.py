"""``qsid reproduce`` for a nonlinear plant (``--system van-der-pol --lifting poly:3``): its figures as offline
HTML, plus the data as JSON.

(a) the error of the lifted model [A_z, B_z] against the unquantized EDMD vs b, LS and BCLS side by side with
their spread and LS's large-data limit where its hypotheses hold; (b) the multi-step prediction error on
held-out runs; (c) the Koopman MPC outcomes per b; (d) eigenvalues of A_z at b = 4 against the unquantized
EDMD's; (e)-(g) 3-D phase portraits (x1, x2, step k) of the plant's own flow (u = 0, green) and the Koopman MPC
loops at b = 2, 4, 6 (LS blue, BCLS red; the unquantized EDMD's loop black). The numbers come from
:class:`qsid_core.studies.KoopmanExperiment` (rows equal to ``qsid sweep``'s); the figures from :mod:`app.figures`.
"""

from __future__ import annotations

import argparse
import time
from typing import TYPE_CHECKING, Any

from .files import write_text
from .output import dumps

if TYPE_CHECKING:
    import plotly.graph_objects as go

    from qsid_core.studies import KoopmanExperiment

    from .runner import Reporter

__all__ = ["run", "PORTRAIT_BITS", "EIGEN_BITS"]

#: Word lengths of the phase portraits and of the eigenvalue panel.
PORTRAIT_BITS, EIGEN_BITS = (2, 4, 6), 4
_LABELS = {"ls": "LS", "bcls": "BCLS"}
#: Options of ``reproduce`` itself (not of the nonlinear sweep).
_OWN = ("--force", "--figure")


def _portrait(ex: KoopmanExperiment, b: int, tag: str) -> go.Figure:
    import numpy as np

    from app.figures import phase_portrait_figure
    from app.figures.palette import COLORS, color

    s = ex.system
    ref = ex.reference_loop()
    loops = {lab: ex.loops(b, e) for e, lab in _LABELS.items()}
    first = loops["LS"]
    assert first is not None and ref is not None
    fig = phase_portrait_figure(
        first.states,
        ref.states[0],
        dims=(0, 1, None),
        names=s.state_names,
        title=f"({tag}) the plant's flow (green) and the Koopman MPC loops at b = {b} (x1, x2, step k)",
        label="LS",
    )
    for tr in fig.data:  # the linear portrait's names, said for the lifted models
        if tr.name and tr.name.endswith("realizations"):
            tr.name = f"LS ({first.states.shape[0]} loops)"
        elif tr.name == "true model":
            tr.name = "unquantized EDMD"
    bc = loops["BCLS"]
    assert bc is not None
    for k, st in enumerate(bc.states):
        ok = np.all(np.isfinite(st), axis=1)
        fig.add_scatter3d(
            x=st[ok, 0], y=st[ok, 1], z=np.arange(st.shape[0])[ok], mode="lines", name="BCLS", legendgroup="BCLS",
            showlegend=k == 0, line=dict(color=color("BCLS"), width=2),
        )  # fmt: skip
    for k, st in enumerate(ex.free_flow(first.states.shape[1] - 1)):
        ok = np.all(np.isfinite(st), axis=1)
        fig.add_scatter3d(
            x=st[ok, 0], y=st[ok, 1], z=np.arange(st.shape[0])[ok], mode="lines", name="free flow (u = 0)",
            legendgroup="flow", showlegend=k == 0, line=dict(color=COLORS["theory"], width=1.5),
        )  # fmt: skip
    return fig


def _panels(ex: KoopmanExperiment, rows: dict[str, list[dict[str, Any]]]) -> list[tuple[str, go.Figure]]:
    import numpy as np

    from app.figures.eigenvalues import eigen_figure
    from app.figures.koopman_eigen import lifted_eigenvalues
    from app.figures.koopman_error import error_figure
    from app.figures.koopman_outcomes import outcomes_figure
    from app.figures.koopman_prediction import prediction_figure

    R, s = ex.config.realizations, ex.system.name
    fa = error_figure(rows, None, ex.config.quantizer.guard, height=460)
    fa.update_layout(
        title=dict(text=f"(a) {s}: error of [A_z, B_z] vs the unquantized EDMD (mean ± std, {R} realizations)")
    )
    fb = prediction_figure(rows, None, ex.reference()[1], ex.horizon, height=420)
    fb.update_layout(
        title=dict(text=f"(b) prediction error over steps 1..{ex.horizon} from each held-out run's start"),
        margin=dict(t=60),
    )
    fc = outcomes_figure(rows, None, height=420)
    fc.update_layout(
        title=dict(text=f"(c) Koopman MPC on the true plant, share of {R} loops per b (LS left · BCLS right)")
    )
    eigs = {lab: lifted_eigenvalues(ex.models(EIGEN_BITS, e).models) for e, lab in _LABELS.items()}
    fd = eigen_figure(eigs, np.linalg.eigvals(ex.reference()[0].A), height=460)
    fd.data[1].name = "unquantized EDMD"
    fd.update_layout(title=dict(text=f"(d) eigenvalues of A_z at b = {EIGEN_BITS}"), margin=dict(t=60))
    out = [("a_error", fa), ("b_prediction", fb), ("c_outcomes", fc), ("d_eigenvalues", fd)]
    return out + [(f"{t}_phase_b{b}", _portrait(ex, b, t)) for t, b in zip("efg", PORTRAIT_BITS)]


def run(args: argparse.Namespace, rep: Reporter, outdir: Any) -> int:
    """Compute the nonlinear sweep for LS and BCLS and write the figures, ``index.html`` and ``data.json``."""
    import dataclasses
    import html

    from plotly.offline import get_plotlyjs

    from app.figures.presenter import legible_figure
    from qsid_core import QuantizerSpec
    from qsid_core.studies import NO_CERTIFICATES, KoopmanExperiment

    from .figure_out import check_formats, index_page, save_panels
    from .koopman import koopman_config

    formats = check_formats(args.figure)
    plain = argparse.Namespace(**vars(args))
    plain.argv = [a for a in getattr(args, "argv", ()) if a.split("=", 1)[0] not in _OWN]
    typed = {a.split("=", 1)[0] for a in plain.argv}
    q = QuantizerSpec()  # the nonlinear sweep's quantizer where not typed (reproduce's defaults are the letter's)
    for flags, name, value in ((("--dither",), "dither", q.dither), (("--range",), "range_mode", q.range_mode)):
        if not typed & set(flags):
            setattr(plain, name, value)
    if not typed & {"--guard", "--no-guard"}:
        plain.guard = q.guard
    cfg = koopman_config(plain)
    bits = tuple(sorted(set(cfg.bits) | set(PORTRAIT_BITS) | {EIGEN_BITS}))
    ex = KoopmanExperiment(dataclasses.replace(cfg, bits=bits))
    t0 = time.perf_counter()
    rep.stage(f"nonlinear sweep of {ex.system.name}, lifting {cfg.lifting}, LS and BCLS, b = {bits[0]}..{bits[-1]}")
    ex.moments(bits)
    rows = {lab: [ex.row(b, e) for b in bits] for e, lab in _LABELS.items()}
    panels = [(stem, legible_figure(fig)) for stem, fig in _panels(ex, rows)]  # the dashboard's laptop style
    rep.stage(f"writing figures to {outdir}")
    write_text(outdir / "plotly.min.js", get_plotlyjs(), rep)
    written = []
    for stem, fig in panels:
        write_text(outdir / f"{stem}.html", fig.to_html(include_plotlyjs="directory", full_html=True), rep)
        written.append(outdir / f"{stem}.html")
    if formats:
        written += save_panels([(fig, outdir / f"{stem}.{f}") for stem, fig in panels for f in formats], rep)
    data: dict[str, Any] = {"kind": "koopman-reproduce", "system": ex.system.name, "lifting": cfg.lifting}
    data["bits"] = list(bits)
    data |= {"results": rows, "certificates": NO_CERTIFICATES, "unquantized_prediction_error": ex.reference()[1]}
    write_text(outdir / "data.json", dumps(data, indent=None) + "\n", rep)
    c = ex.config
    caption = html.escape(
        f"{ex.system.name}, Koopman/EDMD from quantized data: lifting {cfg.lifting} ({ex.lifting.L} features), "
        f"{c.trajectories} runs x {c.steps} steps, {c.realizations} dither realizations per word length, "
        f"{c.quantizer.dither} dither{', guard band' if c.quantizer.guard else ''}; LS and BCLS. "
        f"Unquantized EDMD's prediction error (steps 1..{ex.horizon}): {ex.reference()[1]:.3g}. "
        f"{NO_CERTIFICATES[:1].upper()}{NO_CERTIFICATES[1:]}."
    )
    page = index_page(f"qsid: {ex.system.name}, Koopman/EDMD from quantized data", caption, panels)
    write_text(outdir / "index.html", page + "\n", rep)
    print(f"wrote {len(written) + 3} files to {outdir}:")
    for p in [*written, outdir / "index.html", outdir / "data.json", outdir / "plotly.min.js"]:
        print(f"  {p.name}  ({p.stat().st_size / 1024:.0f} KiB)")
    rep.stage(f"done in {time.perf_counter() - t0:.2f} s; open {outdir / 'index.html'}")
    return 0
