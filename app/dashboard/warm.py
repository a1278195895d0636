"""Kernels compiled (or loaded from numba's disk cache) before the server says it is ready.

numba compiles a kernel the first time it is called in a process unless its machine code is in the
cache (:func:`qsid_core.kernels.cache_dir`). Without this, the first tab after an install paid the
compiler, and every pool worker loaded the kernels on its first task. :func:`warm` runs a tiny
computation through the same path a tab uses (so the same kernel signatures are compiled), in this
process and then in every pool worker (which then only loads what this process wrote to the cache).

:func:`prefill` then computes and draws a new tab's view once, before the URL is printed: the first
tab finds its results in the shared cache, and plotly's figure code already loaded (building the first
figures of a process took ~0.5 s more than later ones), and the page already compressed by viser.
"""

from __future__ import annotations

import glob
import os
import urllib.request

__all__ = ["needs_compiling", "kernel_names", "warm", "warm_here", "prefill", "fetch_page", "COMPILE_SECONDS"]

#: What the first compile of all kernels takes (measured: 15.1 s cold vs 1.0 s cached for this warm-up on a quiet
#: 2-CPU machine; rounded up for slower ones).
COMPILE_SECONDS = 20

#: The compiled kernels as ``module.function`` (numba names their cache index files after them):
#: :mod:`qsid_core.kernels`' box QP and the compiled closed loop of :mod:`qsid_core.loop_kernel`
#: (the generic quantize-and-accumulate kernel serves only systems of more than
#: :data:`qsid_core.unrolled.MAX_CHANNELS` channels, and is compiled when one is used).
KERNELS = (
    "kernels._box_qp_pdas_py",
    "kernels._chol_solve_py",
    "kernels._pdas_one_py",
    "loop_kernel._box_loop_py",
    "loop_kernel._guess_py",
    "loop_kernel._move_py",
    "loop_kernel._predict_py",
    "loop_kernel._stage_py",
)


def _one_preset_per_size() -> dict:
    """``(channels, states)`` -> a preset system of that size, for every size among the presets (sorted)."""
    from qsid_core.systems import PRESETS

    by_size = {(s.n + s.m, s.n): s for s in (make() for make in PRESETS.values())}
    return dict(sorted(by_size.items(), key=lambda item: item[0]))


def kernel_names() -> list[str]:
    """Every kernel :func:`warm_here` compiles, as numba names its cache index files: :data:`KERNELS` and
    :mod:`qsid_core.unrolled`'s kernel for every preset system's size."""
    gen = [f"qsid_accumulate_p{p}_n{n}._accumulate_chunk_py" for p, n in _one_preset_per_size()]
    return [*KERNELS, *gen]


def needs_compiling() -> bool:
    """True if some kernel has no machine code in numba's cache yet (the first run after an install)."""
    from qsid_core import kernels

    if not kernels.AVAILABLE:
        return False
    d = kernels.cache_dir()
    return not all(glob.glob(os.path.join(d, "**", f"{k}-*.nbi"), recursive=True) for k in kernel_names())


def warm_here() -> int:
    """A tiny computation of a tab, saturated (so the compiled closed loop and the box-QP kernel run too);
    returns this process's pid."""
    from app.dashboard.cache import SharedCache
    from app.dashboard.settings import Values
    from app.dashboard.stages import iter_frames

    v = Values(system="dc-motor", trajectories=4, steps=30, realizations=2, bits=4, mpc_steps=5, u_max=1e-3)
    for _ in iter_frames(v, SharedCache(16 * 2**20), None, 1):
        pass
    _warm_box_qp()
    _warm_sizes()
    return os.getpid()


def _warm_sizes() -> None:
    """The quantize-and-accumulate kernel for every preset system's size (:mod:`qsid_core.unrolled`), through
    the engine's own path on a tiny data set of one system per size."""
    import numpy as np

    from qsid_core import QuantizerSpec, kernels, prepare, quantized_moments, simulate

    if not kernels.AVAILABLE:
        return
    spec = QuantizerSpec()
    for system in _one_preset_per_size().values():
        quantized_moments(prepare(simulate(system, 2, 5, seed=0), spec), [4], spec, np.random.default_rng(0))


def _warm_box_qp() -> None:
    """The box-QP kernel with the argument types the closed loops pass (they reach it only when saturated)."""
    import numpy as np

    from qsid_core.condensed_qp import box_qp_batch

    H = np.eye(2)[None] * 2.0
    g = np.array([[3.0, -3.0]])
    upper, lower = np.array([[True, False]]), np.array([[False, True]])
    box_qp_batch(H, g, np.ones(2), upper, lower)


def warm(pool) -> None:
    """Warm this process, then every worker of ``pool`` (a :class:`~app.dashboard.pool.Pool`)."""
    warm_here()
    pool.each_worker(warm_here, timeout=300)


def prefill(values, cache, executor=None, tasks: int = 1) -> int:
    """Compute the frames of a tab showing ``values`` into ``cache`` and build their figures once.

    Returns the number of frames. Raises what the computation raises (e.g. a
    :class:`~qsid_core.errors.QsidError` for settings that cannot be computed).
    """
    from app.dashboard.render import Renderer
    from app.dashboard.stages import iter_frames

    renderer, n = Renderer(), 0
    for frame in iter_frames(values, cache, executor, tasks):
        for wire in renderer.render(frame).figures.values():
            wire.to_json()  # what viser calls when the figure is sent
        n += 1
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
