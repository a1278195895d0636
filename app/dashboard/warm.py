"""Kernels compiled (or loaded from numba's disk cache) before the server says it is ready.

numba compiles a kernel the first time it is called in a process unless its machine code is in the
cache (:func:`qsid_core.studies.kernel_cache_dir`). Without this, the first tab after an install paid the
compiler, and every pool worker loaded the kernels on its first task. :func:`warm` runs a tiny
computation through the same path a tab uses (so the same kernel signatures are compiled), in this
process and then in every pool worker (which then only loads what this process wrote to the cache).

:func:`prefill` then computes and draws a new tab's view once, before the URL is printed: the first
tab finds its results in the shared cache, and plotly's figure code already loaded (building the first
figures of a process took ~0.5 s more than later ones), and the page already compressed by viser.
"""

from __future__ import annotations

import os
import urllib.request
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from qsid_core.studies import compile_kernels, kernel_steps, kernels_cached
from qsid_core.studies import kernel_names as engine_kernel_names

if TYPE_CHECKING:
    from .startup import StartupReport

__all__ = [
    "needs_compiling",
    "kernel_names",
    "warm",
    "warm_here",
    "prefill",
    "fetch_page",
    "first_tab",
    "COMPILE_SECONDS",
    "COLD_START",
    "WARM_START",
]

#: What the first compile of all kernels takes (measured: 15.1 s cold vs 1.0 s cached for this warm-up on a quiet
#: 2-CPU machine; rounded up for slower ones).
COMPILE_SECONDS = 20
#: How long a whole start takes, said when it begins (measured on the 2-core development machine: the first
#: start after an install 116 s and 2 min 24 s while other jobs ran; a later start 22 s to 70 s).
COLD_START = f"compiling the kernels once: ~{COMPILE_SECONDS} s on a quiet 2-core machine, 2 to 3 minutes on a busy one"
WARM_START = "starting: loading the compiled kernels and computing the first view, 20 s to about a minute"


def _presets() -> list:
    from qsid_core import PRESETS

    return [make() for make in PRESETS.values()]


def kernel_names() -> list[str]:
    """Every kernel :func:`warm_here` compiles, as numba names its cache index files (every preset's size)."""
    return engine_kernel_names(_presets())


def needs_compiling() -> bool:
    """True if some kernel has no machine code in numba's cache yet (the first run after an install)."""
    return not kernels_cached(_presets())


def warm_here(progress: Callable[[int, int, str], None] | None = None) -> int:
    """A tiny computation of a tab, saturated (so the compiled closed loop and the box-QP kernel run too), then
    every other kernel; returns this process's pid. ``progress(k, n, what)`` is told each of the ``n`` steps
    before it runs."""
    from app.dashboard.cache import SharedCache
    from app.dashboard.settings import Values
    from app.dashboard.stages import iter_frames

    presets = _presets()
    n = 1 + len(kernel_steps(presets))
    if progress is not None:
        progress(1, n, "a tiny tab's computation (the closed loop, the box QP, the dc motor's quantizer)")
    v = Values(system="dc-motor", trajectories=4, steps=30, realizations=2, bits=4, mpc_steps=5, u_max=1e-3)
    for _ in iter_frames(v, SharedCache(16 * 2**20), None, 1):
        pass
    compile_kernels(presets, None if progress is None else lambda k, _n, what: progress(k + 1, n, what))
    return os.getpid()


def warm(pool, report: StartupReport | None = None) -> None:
    """Warm this process, then every worker of ``pool`` (a :class:`~app.dashboard.pool.Pool`); ``report`` is told
    each step."""
    warm_here(None if report is None else lambda k, n, what: report.step(f"kernel {k} of {n}: {what}"))
    ex = pool.current
    if ex is None:
        return
    if report is not None:
        report.step(
            "the worker process loads the kernels"
            if pool.workers == 1
            else f"the {pool.workers} worker processes load the kernels"
        )
    warmed: set[int] = set()
    while len(warmed) < pool.workers:  # until every worker ran it (each idle worker takes one of a round)
        warmed |= {f.result() for f in [ex.submit(warm_here) for _ in range(pool.workers)]}


def prefill(values, cache, executor=None, tasks: int = 1, progress: Callable[[Any], None] | None = None) -> int:
    """Compute the frames of a tab showing ``values`` into ``cache`` and build their figures once (``progress``
    is given each frame once drawn).

    Returns the number of frames. Raises what the computation raises (e.g. a
    :class:`~qsid_core.errors.QsidError` for settings that cannot be computed).
    """
    from app.dashboard.render import Renderer
    from app.dashboard.stages import iter_frames

    renderer = Renderer()  # (a linear plant, or a nonlinear one: --lesson koopman, a settings file of one)
    n = 0
    for frame in iter_frames(values, cache, executor, tasks):
        for wire in renderer.render(frame).figures.values():
            wire.to_json()  # what viser calls when the figure is sent
        n += 1
        if progress is not None:
            progress(frame)
    return n


def fetch_page(host: str, port: int, timeout: float = 10.0) -> bool:
    """Request the dashboard's page once over loopback (viser compresses it on the first request);
    True if it answered."""
    host = {"0.0.0.0": "127.0.0.1", "::": "::1", "": "127.0.0.1"}.get(host, host)
    name = f"[{host}]" if ":" in host else host
    req = urllib.request.Request(f"http://{name}:{port}/", headers={"Accept-Encoding": "gzip"})
    opener = urllib.request.build_opener(urllib.request.ProxyHandler({}))  # loopback: never through a proxy
    try:
        with opener.open(req, timeout=timeout) as resp:
            resp.read()
            return resp.status == 200
    except OSError:
        return False


def first_tab(app, report: StartupReport | None = None) -> None:
    """Fetch the page once and compute + draw a new tab's view once, so the first tab is served like later ones
    (``report`` is told how far the view is)."""
    fetch_page(app.host, app.port)
    seen: list = []

    def drawn(frame) -> None:
        done, total = getattr(frame, "done", None), getattr(frame, "total", None)
        if report is not None and done is not None and total and done not in seen:
            seen.append(done)
            report.step(f"computing the first view: {done} of {total} word lengths drawn")

    if report is not None:
        report.step("computing the first view")
    why = app.prefill(drawn) if report is not None else app.prefill()
    if why:  # the server starts anyway
        print(f"qsid dashboard: the first view was not precomputed ({why})", flush=True)
