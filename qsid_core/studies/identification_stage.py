"""The identification stages of an :class:`~qsid_core.studies.experiment.Experiment`: the quantized moments of
every realization (mapped through the experiment's executor) and the models identified from them."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from ..identification.identify import Identified, identify, relative_errors
from ..quantization.moments import Moments, PreparedData, quantized_moments
from ..quantization.quantize import BitsSpec, QuantizerSpec
from .executors import single_threaded_blas
from .stage_cache import Staged
from .stage_results import BitsIdentification

__all__ = ["Progress", "compute_moments", "dither_seeds", "identify_at", "moments_task"]

#: ``progress(done, total, what)``, called as chunks of work finish.
Progress = Callable[[int, int, str], None]


def moments_task(
    prep: PreparedData,
    bits: tuple[int, ...],
    spec: QuantizerSpec,
    seeds: Sequence[np.random.SeedSequence],
    input_bits: BitsSpec = None,
    state_bits: Sequence[int | str] | None = None,
) -> list[list[Moments]]:
    """Quantized moments for a chunk of realizations, ``[realization][b]`` (module level: picklable for
    process pools)."""
    out = []
    with single_threaded_blas():
        for ss in seeds:
            rng = np.random.default_rng(ss) if spec.dither != "none" else None
            out.append(quantized_moments(prep, list(bits), spec, rng, input_bits=input_bits, state_bits=state_bits))
    return out


def dither_seeds(dither_seed: int, realizations: int) -> list[np.random.SeedSequence]:
    """The seed of each realization's dither stream (``SeedSequence(dither_seed).spawn(realizations)``)."""
    return np.random.SeedSequence(dither_seed).spawn(realizations)


def compute_moments(ex: Staged, todo: tuple[int, ...], progress: Progress | None) -> dict[int, list[Moments]]:
    """The moments of every realization at each b of ``todo``, the realizations split into ``ex.tasks`` chunks
    mapped through ``ex.executor``."""
    c = ex.config
    prep = ex.prepared
    seeds = dither_seeds(c.dither_seed, c.realizations)
    size = math.ceil(c.realizations / min(ex.tasks, c.realizations))
    chunks = [seeds[i : i + size] for i in range(0, c.realizations, size)]
    # an executor with a ``share`` hook (e.g. app.distributed.DaskExecutor) sends the data once per worker
    share = getattr(ex.executor, "share", None)
    prep_arg = share(prep) if callable(share) else prep
    futs = [
        ex.executor.submit(moments_task, prep_arg, todo, c.quantizer, ch, c.input_bits, c.state_bits) for ch in chunks
    ]
    per_real: list[list[Moments]] = []
    for i, f in enumerate(futs):
        per_real.extend(f.result())
        if progress:
            progress(i + 1, len(futs), "quantize + identify")
    return {b: [pr[j] for pr in per_real] for j, b in enumerate(todo)}


def identify_at(ex: Staged, b: int, est: str) -> BitsIdentification:
    """The models ``est`` identifies at ``b`` from every realization's moments, with their errors.

    A realization whose data are singular is recorded as failed (NaN model), not raised.
    """
    moms = ex.moments([b])[b]
    if ex.config.noise_known and any(v > 0 for v in ex.config.noise):
        extra = ex.noise_variance()
        moms = [replace(mo, D=mo.noise_variance + extra) for mo in moms]
    sysA, sysB = ex.system.A, ex.system.B
    n, m = sysB.shape
    ids: list[Identified | None] = []
    notes: set[str] = set()
    for mo in moms:
        try:
            ids.append(identify(mo, est))
        except ValueError as exc:  # singular data of one realization: record, don't abort
            ids.append(None)
            notes.add(f"identification failed: {exc}")
    nan_A, nan_B = np.full((n, n), np.nan), np.full((n, m), np.nan)
    A_hat = np.stack([i.A if i is not None else nan_A for i in ids])
    B_hat = np.stack([i.B if i is not None else nan_B for i in ids])
    errs: NDArray[np.float64] = np.array([relative_errors(a, bm, sysA, sysB) for a, bm in zip(A_hat, B_hat)])
    notes |= {i.note for i in ids if i is not None and i.note}
    return BitsIdentification(
        bits=b,
        eps=moms[0].eps,
        A_hat=A_hat,
        B_hat=B_hat,
        err_A=errs[:, 0],
        err_B=errs[:, 1],
        overload=np.array([mo.overload_fraction for mo in moms]),
        fallback=np.array([i is not None and i.fallback for i in ids]),
        notes=sorted(notes),
        failed=np.array([i is None for i in ids]),
        dither=ex.config.quantizer.dither,
    )
