"""``qsid reproduce``: the letter's figure panels (a)-(f) as offline HTML, plus the data as JSON.

(a)/(b) relative errors of A and B against b, (c) the closed-loop MPC cost
against b, (d)-(f) phase portraits of the closed loops for b = 2, 4, 6 (systems with fewer than
three states draw time on the missing axis). Every page
loads ``plotly.min.js`` from its own folder, so the folder works offline. The
numbers come from the engine (through :func:`app.cli.runner.run`); this module
only lays out and writes figures (the builders are :mod:`app.figures`).

For a nonlinear ``--system`` (``--system van-der-pol --lifting poly:3``; :func:`app.cli.study.wanted`) its own
panels: (a) the error of the lifted model [A_z, B_z] against the unquantized EDMD vs b, LS and BCLS side by side
with their spread and LS's large-data limit where its hypotheses hold; (b) the multi-step prediction error on
held-out runs; (c) the Koopman MPC outcomes per b; (d) eigenvalues of A_z at b = 4 against the unquantized EDMD's;
(e)-(g) 3-D phase portraits (x1, x2, step k) of the plant's own flow (u = 0, green) and the Koopman MPC loops at
b = 2, 4, 6 (LS blue, BCLS red; the unquantized EDMD's loop black). The numbers come from
:class:`qsid_core.studies.KoopmanExperiment` (rows equal to ``qsid sweep``'s).
"""

from __future__ import annotations

import argparse
import html
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .figure_out import check_formats, index_page, save_panels
from .files import check_writable, input_files, write_text
from .output import dumps, format_table, g
from .parser import add_run_options
from .runner import UsageError, bits_text, config, system_from_args
from .runner import run as run_sweep
from .study import add_nonlinear_options, koopman_config, wanted

if TYPE_CHECKING:
    from collections.abc import Sequence

    import plotly.graph_objects as go
    from numpy.typing import NDArray

    from qsid_core import Experiment, LTISystem, SweepConfig

    from .runner import Reporter

__all__ = ["HELP", "DESCRIPTION", "add_arguments", "run", "PORTRAIT_BITS", "EIGEN_BITS"]

HELP = "write the letter's figure panels (a)-(f) as offline HTML"
DESCRIPTION = (
    "Write the letter's figure panels as standalone offline HTML: (a)/(b) relative errors of A and B "
    "vs b, (c) MPC cost vs b, (d)-(f) closed-loop phase portraits for b = 2, 4, 6; plus index.html "
    "and data.json."
)
#: Word lengths of the phase portraits (both plant kinds) and of a nonlinear plant's eigenvalue panel.
PORTRAIT_BITS, EIGEN_BITS = (2, 4, 6), 4


def add_arguments(p: argparse.ArgumentParser) -> None:
    from qsid_core import SweepConfig

    add_run_options(p, base=SweepConfig.letter())  # defaults: the letter's settings (no guard band)
    add_nonlinear_options(p)  # --lifting ...: a nonlinear --system (its own panels: _run_nonlinear)
    p.add_argument(
        "--out",
        metavar="DIR",
        required=True,
        help="output directory (created if missing; a non-empty one needs --force)",
    )
    p.add_argument("--force", action="store_true", help="write into a non-empty --out directory (files replaced)")
    p.add_argument(
        "--figure",
        metavar="FMT[,FMT]",
        default=None,
        help="also write every panel as png, svg and/or pdf beside its HTML (drawn offline by a local headless "
        "Chromium, /usr/bin/chromium or $QSID_CHROMIUM; without it only the HTML, with a note why)",
    )


def letter_note(cfg: SweepConfig, system: LTISystem) -> str:
    """One stderr line: the letter's settings this run keeps, and what the options changed."""
    from qsid_core import SweepConfig

    letter = SweepConfig.letter(system)
    q, lq = cfg.quantizer, letter.quantizer
    kept = (
        f"b = {bits_text(letter.bits)}, {letter.realizations} realizations, {letter.trajectories} x "
        f"{letter.steps} samples, u ~ U[-{letter.input_amplitude:g}, {letter.input_amplitude:g}], "
        f"{lq.dither} dither, {lq.range_mode} range from the data, "
        f"{'a' if lq.guard else 'no'} guard band, {letter.estimator.upper()}"
    )
    changed = []
    settings: tuple[tuple[str, Any, Any], ...] = (
        ("bits", cfg.bits, letter.bits),
        ("realizations", cfg.realizations, letter.realizations),
        ("trajectories", cfg.trajectories, letter.trajectories),
        ("steps", cfg.steps, letter.steps),
        ("input amplitude", cfg.input_amplitude, letter.input_amplitude),
        ("dither", q.dither, lq.dither),
        ("range", q.range_mode, lq.range_mode),
        ("guard", q.guard, lq.guard),
        ("estimator", cfg.estimator, letter.estimator),
    )
    for name, a, b in settings:
        if a != b:
            shown = bits_text(a) if name == "bits" else ("on" if a else "off") if name == "guard" else a
            changed.append(f"{name} {shown}")
    return (
        "the letter's settings: " + kept + ("" if not changed else "; changed by your options: " + ", ".join(changed))
    )


def _split_error_panel(fig: go.Figure, col: int) -> go.Figure:
    """One panel (col 1: A, col 2: B) of :func:`app.figures.error_figure` as its own figure."""
    import plotly.graph_objects as go

    ax = "x" if col == 1 else "x2"
    panel = go.Figure()
    for tr in fig.data:
        if (tr.xaxis or "x") != ax:
            continue
        t = tr.__class__(tr)  # a copy
        t.update(xaxis="x", yaxis="y", showlegend=(t.fill != "toself"))
        panel.add_trace(t)
    panel.update_layout(
        template="plotly_white", height=420, margin=dict(l=60, r=20, t=60, b=50), legend=dict(orientation="h", y=-0.2)
    )
    panel.update_yaxes(type="log", exponentformat="power")
    panel.update_xaxes(title_text="word length b [bits]", dtick=2)
    return panel


def portrait_dims(n: int) -> tuple:
    """The states a portrait draws: the first three; ``None`` (time, the step k) for the ones a system lacks."""
    return tuple(i if i < n else None for i in range(3))


def _portrait_title(tag: str, system: LTISystem, b: int, R: int) -> str:
    which = ""
    if system.n == 2:
        which = "; time (step k) on the third axis"
    elif system.n == 1:
        which = "; the state against time (step k)"
    elif system.n > 3:
        names = system.state_names
        which = f"; states 1-3 ({', '.join(names[:3])}) of {system.n} shown, {', '.join(names[3:])} not drawn"
    return f"({tag}) closed loops on the true system, b = {b}, {R} realizations{which}"


def _curve_panels(d: dict, label: str, R: int) -> list:
    """Panels (a)-(c): (file stem, heading, figure)."""
    from app.figures import cost_figure, error_figure

    rows = d["results"]
    err = error_figure({label: rows})
    fa = _split_error_panel(err, 1)
    fa.update_layout(title=f"(a) relative error of A vs b ({label}, mean ± std over {R} realizations)")
    fa.update_yaxes(title_text="‖A − Â‖ / ‖A‖")
    fb = _split_error_panel(err, 2)
    fb.update_layout(title=f"(b) relative error of B vs b ({label}, mean ± std over {R} realizations)")
    fb.update_yaxes(title_text="‖B − B̂‖ / ‖B‖")
    fc = cost_figure({label: rows}, true_cost=d["mpc_cost_true_model"], height=420)
    fc.update_layout(
        title=dict(text=f"(c) closed-loop MPC cost on the true system vs b (mean ± std, {R} realizations)"),
        margin=dict(l=60, r=20, t=60, b=50),
    )
    return [
        ("a_error_A", "(a) relative error in A", fa),
        ("b_error_B", "(b) relative error in B", fb),
        ("c_mpc_cost", "(c) MPC cost", fc),
    ]


def _portrait_panels(
    ex: Experiment, system: LTISystem, label: str, R: int
) -> tuple[list[tuple[str, str, go.Figure]], dict[str, dict[str, Any]], NDArray[Any]]:
    """Panels (d)-(f), the portraits' data for data.json, and the true-model states."""
    from app.figures import phase_portrait_figure

    true_states = ex.true_model_loop().states[0]
    panels: list[tuple[str, str, go.Figure]] = []
    portraits: dict[str, dict[str, Any]] = {}
    for tag, b in zip("def", PORTRAIT_BITS):
        loops = ex.closed_loops(b)
        fig = phase_portrait_figure(
            loops.states,
            true_states,
            dims=portrait_dims(system.n),
            names=system.state_names,
            title=_portrait_title(tag, system, b, R),
            label=label,
        )
        panels.append((f"{tag}_phase_b{b}", f"({tag}) phase portrait, b = {b}", fig))
        portraits[str(b)] = {
            "bits": b,
            "states": loops.states,
            "failed": loops.failed,
            "failures": loops.failure,
            "cost": loops.cost,
        }
    return panels, portraits, true_states


def _index_html(d: dict[str, Any], system: LTISystem, panels: list[tuple[str, str, go.Figure]]) -> str:
    c = d["config"]
    title_sys = f"{system.name}: {system.description}" if system.description else system.name
    caption = (
        f"{html.escape(title_sys)}. {c['trajectories']} trajectories x {c['steps']} samples, "
        f"{c['realizations']} dither realizations per word length, range {html.escape(c['range'])}, "
        f"dither {html.escape(c['dither'])}, estimator {html.escape(c['estimator'])}, MPC horizon "
        f"{c['mpc']['horizon']}, {c['mpc']['steps']} closed-loop steps. Slopes of log10 error per bit: "
        f"A {g(d['slope_A'], '+.3f')}, B {g(d['slope_B'], '+.3f')}; true-model MPC cost "
        f"{g(d['mpc_cost_true_model'], '.4g')}."
    )
    return index_page(f"QSID-MPC letter figure: {system.name}", caption, [(s, f) for s, _, f in panels])


def _out_dir(text: str, force: bool, inputs: Sequence[Path] = ()) -> Path:
    if not text.strip():
        raise UsageError(f"argument --out: give a directory name; got {text!r}")
    outdir = Path(text)
    if outdir.exists() and not outdir.is_dir():
        raise UsageError(f"argument --out: {text!r} exists and is not a directory")
    for inp in inputs:
        if outdir.resolve() in Path(inp).resolve().parents:
            raise UsageError(f"argument --out: {text!r} holds the input file {str(inp)!r}; give another directory")
    if outdir.is_dir() and any(outdir.iterdir()) and not force:
        raise UsageError(
            f"argument --out: {text!r} is not empty; give a new directory or add --force "
            "(files of the same name are replaced)"
        )
    try:
        outdir.mkdir(parents=True, exist_ok=True)  # fail before the run, not after it
    except OSError as exc:
        raise UsageError(f"argument --out: cannot create {text!r}: {exc.strerror or exc}") from None
    check_writable(outdir)
    return outdir


def run(args: argparse.Namespace, rep: Reporter) -> int:
    from plotly.offline import get_plotlyjs

    from app.figures.presenter import legible_figure

    if wanted(args):  # a nonlinear --system: its own figures
        return _run_nonlinear(args, rep, _out_dir(args.out, args.force, input_files(args)))
    system = system_from_args(args)
    formats = check_formats(args.figure)
    outdir = _out_dir(args.out, args.force, input_files(args))
    if args.force and any(outdir.iterdir()):
        rep.line(f"note: --force: files in {outdir} with the same names will be replaced")
    t0 = time.perf_counter()
    rep.line(letter_note(config(args, system, True), system))
    res, ex = run_sweep(args, system, True, rep, extra_bits=PORTRAIT_BITS)
    d = res.to_dict()
    label = "BCLS" if res.config.estimator == "bcls" else "LS"
    R = res.config.realizations
    rep.stage(f"writing figures to {outdir}")
    write_text(outdir / "plotly.min.js", get_plotlyjs(), rep)  # matches the plotly that draws the figures
    portrait_panels, portraits, true_states = _portrait_panels(ex, system, label, R)
    # the dashboard's laptop style: no text under 11 px, one labelled tick per decade on log axes
    panels = [(stem, h, legible_figure(fig)) for stem, h, fig in _curve_panels(d, label, R) + portrait_panels]
    written = []
    for stem, _, fig in panels:
        path = outdir / f"{stem}.html"
        write_text(path, fig.to_html(include_plotlyjs="directory", full_html=True), rep)  # whole or not at all
        written.append(path)
    if formats:
        rep.stage(f"drawing {len(panels)} panels as {', '.join(formats)} in a headless Chromium")
        written += save_panels([(fig, outdir / f"{stem}.{f}") for stem, _, fig in panels for f in formats], rep)
    data = {
        "sweep": d,
        "phase_portraits": {
            "bits": list(PORTRAIT_BITS),
            "drawn_states": [i for i in portrait_dims(system.n) if i is not None],
            "time_axes": [j for j, i in enumerate(portrait_dims(system.n)) if i is None],
            "state_names": list(system.state_names),
            "true_model_states": true_states,
            "by_bits": portraits,
        },
        "system": system.to_dict(),
    }
    write_text(outdir / "data.json", dumps(data, indent=None) + "\n", rep)
    write_text(outdir / "index.html", _index_html(d, system, panels), rep)
    print(format_table(d))
    print(f"wrote {len(written) + 3} files to {outdir}:")
    for p in [*written, outdir / "index.html", outdir / "data.json", outdir / "plotly.min.js"]:
        print(f"  {p.name}  ({p.stat().st_size / 1024:.0f} KiB)")
    rep.stage(f"done in {time.perf_counter() - t0:.2f} s; open {outdir / 'index.html'}")
    return 0


def _run_nonlinear(args: argparse.Namespace, rep: Reporter, outdir: Path) -> int:
    """Compute the nonlinear sweep for LS and BCLS and write the figures, ``index.html`` and ``data.json``."""
    import dataclasses

    from plotly.offline import get_plotlyjs

    from app.figures.presenter import legible_figure
    from app.figures.results import LIFTED_LABELS, lifted_panels
    from qsid_core import QuantizerSpec
    from qsid_core.studies import NO_CERTIFICATES, KoopmanExperiment

    formats = check_formats(args.figure)
    plain = argparse.Namespace(**vars(args))
    plain.argv = [a for a in getattr(args, "argv", ()) if a.split("=", 1)[0] not in ("--force", "--figure")]
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
    rows = {lab: [ex.row(b, e) for b in bits] for e, lab in LIFTED_LABELS.items()}
    panels = [
        (stem, legible_figure(fig)) for stem, fig in lifted_panels(ex, rows, EIGEN_BITS, PORTRAIT_BITS)
    ]  # the dashboard's laptop style
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
