"""The dashboard's update function: panel values -> engine results -> what to draw (no server).

:func:`iter_frames` asks :class:`qsid_core.experiment.Experiment` for the current
word length first (one :class:`Frame` with everything the 3-D view and the
summary need), then fills the curves over the other word lengths chunk by
chunk, yielding a frame whenever enough new rows arrived. All numbers come from
the engine; this module only arranges them for display (:func:`scene_view`,
:func:`build_figures`, :func:`summary_markdown`). ``benchmarks/bench_dashboard.py``
times exactly these functions.
"""

from __future__ import annotations

import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Callable, Iterator, MutableMapping

import numpy as np

from qsid_core.experiment import Experiment
from qsid_core.sweep import summary_row
from qsid_core.systems import LTISystem

from .dashboard_state import ALL_BITS, Values, axes_indices, estimators, mpc_config, resolve_system, sweep_config
from .figures import bound_figure, cost_figure, eigen_figure, error_figure, move_current_bits

__all__ = ["LABELS", "RGB", "Frame", "iter_frames", "SceneView", "scene_view", "build_figures",
           "summary_markdown", "Render", "Renderer", "CLIP", "SPHERE_CAP"]

LABELS = {"ls": "LS", "bcls": "BCLS"}
#: Trajectory colours in the 3-D view (same hues as the plots).
RGB = {"LS": (31, 119, 180), "BCLS": (214, 39, 40), "true": (20, 20, 20)}
#: Display coordinates are clipped to +-CLIP box units (diverging loops would swamp the view).
CLIP = 6.0
#: The bound sphere is drawn at most this many box units wide (larger bounds are drawn capped, as wireframe).
SPHERE_CAP = 1.6


@dataclass
class Frame:
    """One drawable state of a tab: the current b in full, and the rows of every b computed so far.

    Attributes
    ----------
    stage : {"current", "curves"}
        ``"current"``: the current b just finished; ``"curves"``: more word lengths filled.
    rows : dict label -> {b: summary row}
        Rows of :func:`qsid_core.sweep.summary_row` per estimator label.
    loops : dict label -> ClosedLoops at the current b
    """

    stage: str
    values: Values
    system: LTISystem
    bits: int
    labels: tuple
    rows: dict
    done: int
    total: int
    loops: dict
    true_loop: object
    theory: object
    idents: dict
    notes: tuple = ()
    elapsed: float = 0.0
    timings: dict = field(default_factory=dict)

    @property
    def complete(self) -> bool:
        return self.done >= self.total

    def series(self) -> dict:
        """``{label: [rows sorted by b]}`` for :mod:`app.figures`."""
        return {lab: [r[b] for b in sorted(r)] for lab, r in self.rows.items()}

    @property
    def true_cost(self) -> float | None:
        if self.true_loop is None:
            return None
        c = float(self.true_loop.cost[0])
        return c if np.isfinite(c) else None


def iter_frames(
    values: Values,
    cache: MutableMapping | None = None,
    executor=None,
    tasks: int = 1,
    should_stop: Callable[[], bool] | None = None,
    chunk: int = 5,
    min_interval: float = 0.3,
    on_progress: Callable[[int, int, str], None] | None = None,
) -> Iterator[Frame]:
    """Compute what a tab shows for ``values``, current b first, then the curves.

    Parameters
    ----------
    values : Values
    cache : mapping, optional
        Shared :class:`~app.dashboard_state.SharedCache` (anything a change does not touch is reused).
    executor, tasks
        Passed to :class:`~qsid_core.experiment.Experiment` (e.g. the dashboard's process pool).
    should_stop : callable, optional
        Polled between chunks; True ends the iteration (newer settings arrived).
    chunk : int
        Word lengths quantized per pass over the data.
    min_interval : float
        A "curves" frame is yielded when this many seconds passed since the last one, and at the end.
    on_progress : callable(done, total, text), optional
        Called before each chunk ("computing b=5..9 (6/16)").

    Raises
    ------
    qsid_core.errors.QsidError
        Bad settings (:class:`~app.dashboard_state.InputError`), data overflow, ... in plain words.
    """
    stop = should_stop or (lambda: False)
    t0 = time.perf_counter()
    choice = resolve_system(values)
    system = choice.system
    cfg = sweep_config(values, system)
    ests = estimators(values.identification)
    labels = tuple(LABELS[e] for e in ests)
    ex = Experiment(cfg, executor=executor, tasks=tasks, cache=cache)
    b = int(values.bits)
    n = system.n
    total = len(ALL_BITS)
    if on_progress:
        on_progress(0, total, f"computing b={b} (1/{total})")
    idents = {LABELS[e]: ex.identification(b, e) for e in ests}
    th = ex.theory(b)
    loops = {LABELS[e]: ex.closed_loops(b, e) for e in ests}
    true_loop = ex.true_model_loop()
    rows = {lab: {b: summary_row(n, idents[lab], th, loops[lab])} for lab in labels}
    notes = list(choice.notes)
    t1 = time.perf_counter()
    common = dict(values=values, system=system, bits=b, labels=labels, loops=loops, true_loop=true_loop,
                  theory=th, idents=idents, notes=tuple(notes))
    yield Frame("current", rows={k: dict(v) for k, v in rows.items()}, done=1, total=total,
                elapsed=t1 - t0, timings={"current": t1 - t0}, **common)
    rest = [x for x in ALL_BITS if x != b]
    parts = [rest[i:i + chunk] for i in range(0, len(rest), chunk)]
    # quantization of the next chunk (the heavy part, in the executor) overlaps with the
    # closed loops of this one (in this thread)
    ahead = _Prefetch(ex, parts, stop)
    last = time.perf_counter()
    done = 1
    try:
        k = 0
        while k < len(parts):
            if stop():
                return
            if on_progress:
                on_progress(done, total, f"computing b={parts[k][0]}..{parts[k][-1]} ({done + 1}/{total})")
            ahead.wait(k)
            if executor is not None and ahead.finished:
                # quantization done (or cached): spread the remaining closed loops over the executor at once
                part, k = [x for p in parts[k:] for x in p], len(parts)
                for e, lps in _loops_all(ex, part, ests).items():
                    for x in part:
                        rows[LABELS[e]][x] = summary_row(n, ex.identification(x, e), ex.theory(x), lps[x])
            else:
                # closed loops here, side by side with the quantization of the next chunk in the executor
                part, k = parts[k], k + 1
                for e in ests:
                    for x in part:
                        rows[LABELS[e]][x] = summary_row(n, ex.identification(x, e), ex.theory(x),
                                                         ex.closed_loops(x, e))
            done += len(part)
            now = time.perf_counter()
            if done >= total or now - last >= min_interval:
                last = now
                yield Frame("curves", rows={lab: dict(r) for lab, r in rows.items()}, done=done, total=total,
                            elapsed=now - t0, timings={"current": t1 - t0, "curves": now - t0}, **common)
    finally:
        ahead.cancel()


def _loops_all(ex: Experiment, bits: list, ests: tuple) -> dict:
    """``ex.closed_loops_many(bits, e)`` for every estimator, submitted together (no idle workers in between)."""
    if len(ests) == 1:
        return {ests[0]: ex.closed_loops_many(bits, ests[0])}
    with ThreadPoolExecutor(len(ests)) as tp:
        return dict(zip(ests, tp.map(lambda e: ex.closed_loops_many(bits, e), ests)))


class _Prefetch:
    """Computes ``ex.moments(part)`` for each part in a helper thread, at most one part ahead of the reader."""

    def __init__(self, ex: Experiment, parts: list, stop: Callable[[], bool]):
        self.ex, self.parts, self.stop = ex, parts, stop
        self.cond = threading.Condition()
        self.ready = -1  # last part whose moments are cached
        self.reading = 0  # part the reader waits for / works on
        self.error: BaseException | None = None
        self.cancelled = False
        self.last_cost = 0.0
        self.thread = threading.Thread(target=self._run, name="qsid-prefetch", daemon=True)
        self.thread.start()

    def _run(self) -> None:
        try:
            for k, part in enumerate(self.parts):
                with self.cond:  # at most one expensive part ahead (cheap parts: run through)
                    while not self.cancelled and k > self.reading + 1 and self.last_cost > 0.15:
                        self.cond.wait(0.5)
                    if self.cancelled:
                        return
                if self.stop():
                    return
                t = time.perf_counter()
                self.ex.moments(part)
                self.last_cost = time.perf_counter() - t
                with self.cond:
                    self.ready = k
                    self.cond.notify_all()
        except BaseException as exc:  # handed to the reader
            with self.cond:
                self.error = exc
                self.cond.notify_all()

    def wait(self, k: int) -> None:
        with self.cond:
            self.reading = k
            self.cond.notify_all()
            while self.ready < k and self.error is None:
                if not self.thread.is_alive() and self.ready < k:
                    break
                self.cond.wait(0.2)
            if self.error is not None:
                raise self.error
        if self.ready < k:  # the helper stopped early (stop() turned true): compute here
            self.ex.moments(self.parts[k])

    @property
    def finished(self) -> bool:
        """Every part's moments are cached."""
        return self.ready >= len(self.parts) - 1

    def cancel(self) -> None:
        with self.cond:
            self.cancelled = True
            self.cond.notify_all()


# ----- 3-D view ----------------------------------------------------------------------------

@dataclass
class SceneView:
    """Arrays for the viser scene, in display units (state / ``scale``).

    ``segments`` holds one polyline per realization (and per estimator), as
    (N, 2, 3) line segments; failed realizations are collapsed onto the start
    point; coordinates are clipped to +-:data:`CLIP`.
    """

    segments: np.ndarray
    colors: np.ndarray
    true_segments: np.ndarray
    start: np.ndarray
    scale: float
    sphere_radius: float
    sphere_capped: bool
    delta: float | None
    axis_names: tuple
    failed: int
    clipped: int
    polylines: int


def _to_segments(states: np.ndarray, dims: tuple, scale: float, start: np.ndarray) -> tuple:
    """(R, T+1, n) trajectories -> (R*T, 2, 3) display segments, #failed, #clipped."""
    R, T1, _ = states.shape
    P = np.zeros((R, T1, 3))
    for j, d in enumerate(dims):
        if d is not None:
            P[:, :, j] = states[:, :, d] / scale
    bad = ~np.all(np.isfinite(P.reshape(R, -1)), axis=1)
    P[bad] = start
    clipped = int(np.sum(np.any(np.abs(P.reshape(R, -1)) > CLIP, axis=1)))
    np.clip(P, -CLIP, CLIP, out=P)
    seg = np.stack([P[:, :-1, :], P[:, 1:, :]], axis=2).reshape(-1, 2, 3)
    return seg, int(bad.sum()), clipped


def scene_view(frame: Frame, axes: str | None = None) -> SceneView:
    """What the 3-D phase portrait draws for ``frame``: closed loops at the current b, the
    true-model loop, the start point, and the bound sphere, all divided by one display scale.

    The display scale is the largest |state| of the true-model loop on the drawn axes
    (so that loop fits the unit box); the sphere of radius delta(eps) uses the same scale.
    """
    sysm = frame.system
    names = sysm.state_names
    dims = axes_indices(axes if axes is not None else frame.values.axes, names)
    ts = frame.true_loop.states[0]
    x0 = mpc_config(frame.values, sysm).resolve(sysm)["x0"]  # the engine's start state (also if loops failed)
    sel = [d for d in dims if d is not None]
    ref = ts[:, sel]
    ref = ref[np.all(np.isfinite(ref), axis=1)]
    scale = float(np.abs(ref).max()) if ref.size else 0.0
    if not np.isfinite(scale) or scale <= 0:
        scale = float(np.abs(x0[sel]).max())
        scale = scale if np.isfinite(scale) and scale > 0 else 1.0
    start = np.array([x0[d] / scale if d is not None else 0.0 for d in dims])
    segs, cols, failed, clipped, poly = [], [], 0, 0, 0
    for lab in frame.labels:
        st = frame.loops[lab].states
        s, f, c = _to_segments(st, dims, scale, start)
        segs.append(s)
        cols.append(np.broadcast_to(np.array(RGB[lab], dtype=np.uint8), s.shape))
        failed += f
        clipped += c
        poly += st.shape[0]
    tseg, _, _ = _to_segments(ts[None], dims, scale, start)
    delta = frame.theory.delta
    ok = delta is not None and np.isfinite(delta) and delta > 0
    radius = float(delta) / scale if ok else 0.0
    capped = radius > SPHERE_CAP
    return SceneView(
        segments=np.concatenate(segs).astype(np.float32), colors=np.ascontiguousarray(np.concatenate(cols)),
        true_segments=tseg.astype(np.float32), start=start, scale=scale,
        sphere_radius=min(radius, SPHERE_CAP), sphere_capped=capped, delta=float(delta) if ok else None,
        axis_names=tuple(names[d] if d is not None else "-" for d in dims), failed=failed, clipped=clipped,
        polylines=poly,
    )


# ----- plots and summary ---------------------------------------------------------------------

def build_figures(frame: Frame, which=("error", "cost", "bound", "eigen")) -> dict:
    """Plotly figures for ``frame`` (rows may be partial: missing word lengths are simply absent)."""
    series = frame.series()
    out = {}
    if "error" in which:
        out["error"] = error_figure(series, current_bits=frame.bits, height=300)
    if "cost" in which:
        out["cost"] = cost_figure(series, true_cost=frame.true_cost, current_bits=frame.bits, height=260)
    if "bound" in which:
        out["bound"] = bound_figure(series, current_bits=frame.bits, height=260)
    if "eigen" in which:
        eigs = {lab: frame.idents[lab].eigenvalues for lab in frame.labels}
        out["eigen"] = eigen_figure(eigs, frame.system.eigenvalues, height=300,
                                    title=f"eigenvalues of Â at b = {frame.bits}")
    return out


def _g(x, fmt=".3g") -> str:
    return "–" if x is None else format(x, fmt)


def _failures(row: dict, lp) -> str:
    mc = row.get("mpc_cost") or {}
    k = mc.get("failed", 0)
    if not k:
        return "none"
    kinds = ", ".join(f"{n} {kind}" for kind, n in sorted(mc.get("failures", {}).items()))
    return f"{k}/{len(lp.failure)} ({kinds})"


def summary_markdown(frame: Frame) -> str:
    """The numeric summary at the current b: eps per channel, errors, overload, failures."""
    sysm = frame.system
    b = frame.bits
    first = frame.rows[frame.labels[0]][b]
    eps_x = ", ".join(f"{nm} {e:.3g}" for nm, e in zip(sysm.state_names, first["eps_x"]))
    eps_u = ", ".join(f"{nm} {e:.3g}" for nm, e in zip(sysm.input_names, first["eps_u"]))
    lines = [
        f"**{sysm.name}**, b = **{b}** bits, {frame.values.realizations} dither realizations, "
        f"{frame.values.trajectories} × {frame.values.steps} samples",
        "",
        f"ε states: {eps_x}  ",
        f"ε inputs: {eps_u}  ",
        f"overload: {100 * first['overload_fraction']:.2f} % of samples · "
        f"δ(ε) = {_g(first['ultimate_bound'])}",
        "",
        "| | ‖ΔA‖/‖A‖ | ‖ΔB‖/‖B‖ | MPC cost | MPC failures |",
        "|---|---|---|---|---|",
    ]
    for lab in frame.labels:
        r = frame.rows[lab][b]
        cost = (r.get("mpc_cost") or {}).get("mean")
        lines.append(f"| {lab} | {_g(r['err_A']['mean'])} | {_g(r['err_B']['mean'])} | {_g(cost, '.4g')} | "
                     f"{_failures(r, frame.loops[lab])} |")
    lines.append(f"| Thm 1 | {_g(first['err_A_theory'])} | {_g(first['err_B_theory'])} | | |")
    lines.append("")
    tl = frame.true_loop
    why = f" (its MPC failed: {tl.messages[0]})" if tl is not None and tl.failure and tl.failure[0] else ""
    lines.append(f"MPC cost with the true model: {_g(frame.true_cost, '.4g')}{why}")
    notes = list(frame.notes)
    for lab in frame.labels:
        k = frame.rows[lab][b].get("ident_failures") or 0
        if k:
            why = "; ".join(x for x in frame.idents[lab].notes if x.startswith("identification failed"))[:200]
            notes.append(f"{lab} identification failed in {k} of {frame.values.realizations} realizations "
                         f"(their loops are not drawn): {why}")
    if "BCLS" in frame.labels:
        r = frame.rows["BCLS"][b]
        if r["bcls_fallbacks"]:
            why = "; ".join(frame.idents["BCLS"].notes[:2])
            notes.append(f"BCLS fell back to LS in {r['bcls_fallbacks']} of {frame.values.realizations} "
                         f"realizations: {why}")
    for lab in frame.labels:
        msgs = sorted({m for m in frame.loops[lab].messages if m})
        if msgs:
            notes.append(f"{lab} MPC: " + "; ".join(msgs[:2]) + (" …" if len(msgs) > 2 else ""))
    if frame.theory.bound_note:
        notes.append(f"bound: {frame.theory.bound_note}")
    if notes:
        lines.append("")
        lines += [f"- {x}" for x in notes]
    return "\n".join(lines)


@dataclass
class Render:
    """What to push to a tab for one frame (None / missing = leave as is)."""

    scene: SceneView | None
    summary: str | None
    figures: dict


class Renderer:
    """Decides what one tab redraws for each frame, remembering what it drew last.

    * a "current" frame redraws the 3-D view and the summary, the eigenvalue plot
      if the models changed, and moves the current-b marker of the other plots;
    * a "curves" frame rebuilds the error, cost and bound plots only if their rows
      changed (a pure b change leaves them alone and just moves the marker).
    """

    CURVES = ("error", "cost", "bound")

    def __init__(self):
        self.figures: dict = {}
        self._rows_key = None
        self._eig_key = None

    def render(self, frame: Frame, axes: str | None = None) -> Render:
        out: dict = {}
        scene = summary = None
        if frame.stage == "current":
            scene = scene_view(frame, axes)
            summary = summary_markdown(frame)
            eig_key = (frame.bits, tuple(id(frame.idents[lab]) for lab in frame.labels))
            if eig_key != self._eig_key:
                out.update(build_figures(frame, ("eigen",)))
                self._eig_key = eig_key
        rows_key = (frame.labels, frame.true_cost,
                    tuple((lab, b, repr(r)) for lab in frame.labels for b, r in sorted(frame.rows[lab].items())))
        if frame.stage == "curves" and rows_key != self._rows_key:
            out.update(build_figures(frame, self.CURVES))
            self._rows_key = rows_key
        else:
            for name in self.CURVES:
                if name in self.figures:
                    out[name] = move_current_bits(self.figures[name], frame.bits)
        self.figures.update(out)
        return Render(scene, summary, out)
