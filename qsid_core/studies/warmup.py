"""The engine's compiled kernels, compiled ahead of use, and whether numba's disk cache holds them.

numba compiles a kernel the first time a process calls it unless its machine code is in the cache
(:func:`kernel_cache_dir`). A front end that wants its first result fast calls :func:`compile_kernels`
once at start (the dashboard does, before it prints its URL) and :func:`kernels_cached` to say whether
that will take long.
"""

from __future__ import annotations

import glob
import os
from collections.abc import Callable, Iterable

import numpy as np

from ..control.condensed_qp import box_qp_batch
from ..identification import parse_lifting, quantized_lifted_realizations
from ..plant import get_nonlinear, simulate_nonlinear
from ..plant.data import simulate
from ..plant.lti import LTISystem
from ..quantization import kernels
from ..quantization.moments import prepare, quantized_moments
from ..quantization.quantize import QuantizerSpec

__all__ = [
    "COMPILED_KERNELS",
    "Progress",
    "compile_kernels",
    "kernel_cache_dir",
    "kernel_names",
    "kernel_steps",
    "kernels_cached",
    "one_per_size",
]

#: ``progress(step, steps, what)``: called before each step of :func:`compile_kernels` (1-based ``step`` of
#: ``steps``; ``what`` names the kernel in plain words). The engine never prints; a front end may.
Progress = Callable[[int, int, str], None]

#: The compiled kernels as ``module.function`` (numba names their cache index files after them): the box QP,
#: the compiled saturated closed loop and the quantize-lift-accumulate kernel of EDMD (one for every monomial
#: dictionary and plant size: the dictionary is data to it). The quantize-and-accumulate kernel of linear
#: plants is generated per system size (see :func:`kernel_names`); the generic one serves larger systems and
#: is compiled when one is used.
COMPILED_KERNELS = (
    "edmd_kernel._block_sums_py",
    "edmd_kernel._kernel_py",
    "edmd_kernel._lift_block_py",
    "edmd_kernel._load_block_py",
    "edmd_kernel._quantize_row_py",
    "edmd_kernel._tile14_py",
    "edmd_kernel._tile24_py",
    "kernels._box_qp_pdas_py",
    "kernels._chol_solve_py",
    "kernels._pdas_one_py",
    "loop_kernel._box_loop_py",
    "loop_kernel._guess_py",
    "loop_kernel._move_py",
    "loop_kernel._predict_py",
    "loop_kernel._stage_py",
)


def kernel_cache_dir() -> str:
    """Where numba keeps the engine's compiled kernels."""
    return kernels.cache_dir()


def one_per_size(systems: Iterable[LTISystem]) -> dict[tuple[int, int], LTISystem]:
    """``(channels, states)`` -> the first of ``systems`` of that size, sorted by size."""
    by_size: dict[tuple[int, int], LTISystem] = {}
    for s in systems:
        by_size.setdefault((s.n + s.m, s.n), s)
    return dict(sorted(by_size.items()))


def kernel_names(systems: Iterable[LTISystem]) -> list[str]:
    """Every kernel :func:`compile_kernels` compiles for ``systems``, as numba names its cache index files."""
    gen = [f"qsid_accumulate_p{p}_n{n}._accumulate_chunk_py" for p, n in one_per_size(systems)]
    return [*COMPILED_KERNELS, *gen]


def kernels_cached(systems: Iterable[LTISystem]) -> bool:
    """True if every kernel for ``systems`` has machine code in numba's cache (always True without numba)."""
    if not kernels.AVAILABLE:
        return True
    d = kernels.cache_dir()
    if d.endswith("__pycache__"):  # numba's default: a __pycache__ beside each kernel's own module
        d = os.path.dirname(os.path.dirname(os.path.dirname(kernels.__file__)))
    return all(glob.glob(os.path.join(d, "**", f"{k}-*.nbi"), recursive=True) for k in kernel_names(systems))


def _box_qp() -> None:
    H = np.eye(2)[None] * 2.0
    g = np.array([[3.0, -3.0]])
    upper, lower = np.array([[True, False]]), np.array([[False, True]])
    box_qp_batch(H, g, np.ones(2), upper, lower)


def _edmd() -> None:
    vdp = get_nonlinear("van-der-pol")
    data = simulate_nonlinear(vdp, 2, 5, seed=0)
    quantized_lifted_realizations(data, parse_lifting("poly:2", 2), [4], QuantizerSpec())


def _accumulate(system: LTISystem) -> Callable[[], None]:
    def run() -> None:
        spec = QuantizerSpec()
        quantized_moments(prepare(simulate(system, 2, 5, seed=0), spec), [4], spec, np.random.default_rng(0))

    return run


def kernel_steps(systems: Iterable[LTISystem]) -> list[tuple[str, Callable[[], None]]]:
    """The steps of :func:`compile_kernels` for ``systems``: ``(what, run)``, ``what`` in plain words."""
    steps: list[tuple[str, Callable[[], None]]] = [("the box QP", _box_qp), ("the EDMD (Koopman) kernel", _edmd)]
    for (p, n), system in one_per_size(systems).items():
        m = p - n
        steps.append((f"the quantizer for {n} states and {m} input{'s' * (m > 1)}", _accumulate(system)))
    return steps


def compile_kernels(systems: Iterable[LTISystem], progress: Progress | None = None) -> None:
    """Compile (or load from the cache) the box QP, the EDMD kernel and the quantize-and-accumulate kernel for
    every size among ``systems``, through the engine's own paths on tiny data. The compiled closed loop is
    compiled by the first saturated loop (see :func:`qsid_core.control.run_closed_loops`). ``progress`` (see
    :data:`Progress`) is told each step before it runs."""
    if not kernels.AVAILABLE:
        return
    steps = kernel_steps(systems)
    for i, (what, run) in enumerate(steps, 1):
        if progress is not None:
            progress(i, len(steps), what)
        run()
