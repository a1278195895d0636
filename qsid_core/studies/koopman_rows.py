"""The rows of a nonlinear sweep (:mod:`~qsid_core.studies.koopman_sweep`): each realization's model at each
word length, its errors against the unquantized EDMD and its prediction error, recorded; then per word
length the statistics over the realizations, the closed loops and the estimator's large-data limit."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..control import KoopmanLoops, MPCConfig, run_koopman_loops
from ..errors import ConfigError, IdentificationError, MPCFailure
from ..identification import (
    KoopmanModel,
    LargeDataLimit,
    LiftedMoments,
    Lifting,
    MonomialLifting,
    edmd,
    lifted_error,
    prediction_errors,
)
from ..plant import NonlinearDataset, NonlinearSystem
from ..quantization import QuantizerSpec

__all__ = ["ACC_KEYS", "large_data_entry", "loop_entries", "no_exact_correction", "predict", "record", "row"]

#: What :func:`record` and :func:`predict` collect per word length, one entry per realization.
ACC_KEYS = ("G", "A", "B", "pred", "fallback", "notes", "models", "over", "eps")


def _stats(v: list[float]) -> dict[str, float]:
    a = np.asarray(v, dtype=float)
    a = a[np.isfinite(a)]
    if a.size == 0:
        return {"mean": float("nan"), "std": float("nan")}
    return {"mean": float(a.mean()), "std": float(a.std())}


def record(
    acc: dict[str, list[Any]],
    mom: LiftedMoments,
    estimator: str,
    lifting: Lifting,
    ref: KoopmanModel,
) -> None:
    """Add one realization at one word length to ``acc``: its model (None when identification failed), the
    lifted errors against ``ref``, the overload fraction, ``eps`` and notes (the prediction error:
    :func:`predict`)."""
    acc["over"].append(mom.overload_fraction)
    acc["eps"].append(mom.eps)
    try:
        model: KoopmanModel | None = edmd(mom, lifting.C, estimator)
    except IdentificationError as exc:
        model = None
        acc["notes"].append(str(exc))
    if model is None:
        for k in ("G", "A", "B"):
            acc[k].append(float("nan"))
    else:
        eG, eA, eB = lifted_error(model, ref)
        acc["G"].append(eG)
        acc["A"].append(eA)
        acc["B"].append(eB)
        acc["fallback"].append(model.fallback)
        if model.note:
            acc["notes"].append(model.note)
    acc["models"].append(model)


def predict(per: list[dict[str, list[Any]]], lifting: Lifting, held: NonlinearDataset, horizon: int) -> None:
    """Add the prediction error on ``held`` of the model last recorded in each of ``per`` (NaN where
    identification failed), all in one batch."""
    models = [acc["models"][-1] for acc in per]
    ok = [mo for mo in models if mo is not None]
    errs = iter(prediction_errors(ok, lifting, held, horizon))
    for acc, mo in zip(per, models, strict=True):
        acc["pred"].append(float("nan") if mo is None else next(errs))


def large_data_entry(
    limit: LargeDataLimit | None, estimator: str, ref: KoopmanModel, correction: str
) -> dict[str, Any]:
    """The row's ``large_data`` entry: where the estimator goes with many samples (:func:`large_data_limit`)."""
    if estimator == "bcls":
        if correction:
            return {"err_G": None, "note": f"no exact limit: {correction}"}
        return {"err_G": 0.0, "note": "the de-biased moments are unbiased: the limit is the unquantized EDMD"}
    if limit is None or limit.model is None:
        return {"err_G": None, "note": "not computed" if limit is None else limit.note}
    return {"err_G": lifted_error(limit.model, ref)[0], "note": ""}


def row(
    b: int, acc: dict[str, list[Any]], lifting: Lifting, system: NonlinearSystem, mpc: MPCConfig | None, radius: float
) -> dict[str, Any]:
    """The result row of word length ``b`` from its realizations ``acc``, with the closed loops of ``mpc`` (none
    when None) judged converged within ``radius``."""
    n = system.n
    row: dict[str, Any] = {
        "bits": b,
        "eps_x": np.asarray(acc["eps"][0][:n]).tolist(),
        "eps_u": np.asarray(acc["eps"][0][n:]).tolist(),
        "err_G": _stats(acc["G"]),
        "err_A": _stats(acc["A"]),
        "err_B": _stats(acc["B"]),
        "prediction_error": _stats(acc["pred"]),
        "overload_fraction": float(np.mean(acc["over"])),
        "bcls_fallbacks": int(sum(acc["fallback"])),
        "ident_failures": int(sum(m is None for m in acc["models"])),
        "realizations": len(acc["models"]),
        "stabilized_fraction": None,
        "closed_loop_outcomes": None,
        "within_radius": None,
        "settled_offset": None,
        "notes": sorted(set(acc["notes"])),
    }
    if mpc is not None:
        try:
            loops = run_koopman_loops(acc["models"], lifting, system, mpc, radius)
        except MPCFailure as exc:  # pragma: no cover - run_koopman_loops records failures per loop
            raise ConfigError(str(exc)) from None
        row.update(loop_entries(loops))
    return row


def loop_entries(loops: KoopmanLoops) -> dict[str, Any]:
    """A row's loop entries: the stabilized (converged) share, the outcome counts, how many ended within the
    convergence radius and the settled offsets' median and max (:class:`~qsid_core.control.KoopmanLoops`)."""
    return {
        "stabilized_fraction": loops.converged_fraction,
        "closed_loop_outcomes": loops.counts(),
        "within_radius": int(np.sum(loops.within_radius)),
        "settled_offset": loops.offset_stats(),
    }


def no_exact_correction(lifting: Lifting, spec: QuantizerSpec) -> str:
    """Why the de-biased moments are not exact for this dictionary and dither ("" when they are)."""
    if not isinstance(lifting, MonomialLifting):
        return f"the radial functions of {lifting.spec} have no exact correction (LS is used)"
    if spec.dither != "subtractive":
        return f"the Bernoulli correction is exact for subtractive dither only, not {spec.dither}"
    return ""
