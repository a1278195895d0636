"""The small-gain certificate of "how many bits" (``b_robust``) and the check of its hypotheses.

With ``(A^, B^)`` a model and ``K^`` the gain of the MPC built on it (its unconstrained law),
the small-gain theorem gives stability of ``A - B K^`` when
``||(A - A^) - (B - B^) K^||_2 < r_C(A^ - B^ K^)``
(:func:`qsid_core.control.stability_radius.small_gain_margin`). :func:`predicted_small_gain`
runs that test for Theorem 1's model, :func:`realized_small_gain` for each loop's own model,
and :func:`certificate` decides from both, with Theorem 1's hypotheses checked on the data
(see :mod:`qsid_core.studies.bits`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from ..control.stability_radius import small_gain_holds
from .experiment import Experiment

if TYPE_CHECKING:
    from ..control.loop_results import ClosedLoops
    from .stage_results import BitsIdentification

__all__ = [
    "CERTIFY_TOLERANCE",
    "certificate",
    "certified_own_models",
    "certified_own_models_at",
    "predicted_small_gain",
    "predicted_small_gains",
    "realized_small_gain",
]

#: b_robust through Theorem 1's model needs the measured errors within this relative distance of the
#: prediction, and the small-gain test to hold with this margin.
CERTIFY_TOLERANCE = 0.25


def predicted_small_gain(ex: Experiment, b: int) -> tuple[float, float]:
    """``(perturbation, radius)`` of the small-gain test for Theorem 1's predicted model at ``b``
    (one word length of :func:`predicted_small_gains`)."""
    return predicted_small_gains(ex, (b,))[b]


def predicted_small_gains(ex: Experiment, bits: Sequence[int]) -> dict[int, tuple[float, float]]:
    """Per b of ``bits``: ``(perturbation, radius)`` of the small-gain test for Theorem 1's predicted model.

    ``K^`` is the first gain of the MPC's Riccati recursion on the predicted model
    (its terminal weight: the configured ``Qf`` or the model's DARE solution).
    ``(inf, 0)`` where no MPC can be built on that model. Cached in ``ex`` per b; the word lengths not
    in the cache are computed in one batch.
    """
    from ..control.mpc import MPCConfig
    from ..control.riccati import dare_many, lq_parts
    from ..control.stability_radius import small_gain_margins

    mcfg = ex.config.mpc or MPCConfig()
    out: dict[int, tuple[float, float]] = {}
    todo: list[tuple[int, Any, np.ndarray]] = []  # (b, key, G_pred) not in the cache
    for b in dict.fromkeys(bits):
        G = ex.theory(b).G_pred
        k = ex.keys.small_gain(b, G)
        try:
            out[b] = cast("tuple[float, float]", ex.cache.mapping[k])
        except KeyError:  # (a shared, bounded cache may also have dropped it: computed again)
            todo.append((b, k, G))
    if not todo:
        return out
    sysm = ex.system
    n, w = sysm.n, mcfg.resolve(sysm)
    G = np.stack([t[2] for t in todo])
    Ah, Bh = G[:, :, :n], G[:, :, n:]
    res = np.tile([math.inf, 0.0], (len(todo), 1))
    if w.Qf is not None:
        Qf, ok = np.broadcast_to(np.asarray(w.Qf, float), Ah.shape).copy(), np.ones(len(todo), dtype=bool)
    else:
        Qf, ok = dare_many(Ah, Bh, w.Q, w.R)
    if ok.any():
        with np.errstate(all="ignore"):
            K = lq_parts(Ah[ok], Bh[ok], w.Q, w.R, Qf[ok], np.zeros(n), mcfg.horizon, w.u_max, None, None).K[:, 0]
        fin = np.all(np.isfinite(K.reshape(K.shape[0], -1)), axis=1)
        idx = np.flatnonzero(ok)[fin]
        if idx.size:
            pert, rad = small_gain_margins(sysm.A, sysm.B, Ah[idx], Bh[idx], K[fin])
            res[idx] = np.stack([pert, rad], axis=1)
    new = [(t[1], (float(r[0]), float(r[1]))) for t, r in zip(todo, res)]
    ex.cache.store(new)
    out.update({t[0]: v for t, (_, v) in zip(todo, new)})
    return {b: out[b] for b in bits}


def realized_small_gain(ident: BitsIdentification, loops: ClosedLoops, A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Per realization: whether the small-gain test certifies its loop with its *own* model error.

    ``K^`` is read from the loop's unconstrained law (``A - B K^`` has the loop's
    spectral radius). A sufficient condition: every certified loop has spectral
    radius below 1 (tested), not the other way round.

    Returns
    -------
    ndarray of bool, shape (R,) (False where the loop has no MPC).
    """
    out = np.zeros(len(ident.err_A), dtype=bool)
    idx = [r for r, K in enumerate(loops.gains) if K is not None]
    gains = [K for K in loops.gains if K is not None]
    if idx:
        out[idx] = small_gain_holds(A, B, ident.A_hat[idx], ident.B_hat[idx], np.stack(gains))
    return out


def certified_own_models(ex: Experiment, b: int, estimator: str) -> int:
    """How many of ``ex``'s closed loops at ``b`` (models by ``estimator``) :func:`realized_small_gain`
    certifies with their own model error (:func:`certified_own_models_at` for one b)."""
    return certified_own_models_at(ex, (b,), estimator)[b]


def certified_own_models_at(ex: Experiment, bits: Sequence[int], estimator: str) -> dict[int, int]:
    """Per b of ``bits``: how many of ``ex``'s closed loops at b (models by ``estimator``)
    :func:`realized_small_gain` certifies with their own model error.

    Each loop's verdict depends only on its model and its gain ``K^`` (the unconstrained law: not the
    input bound, the start or the loop's noise), so it is cached per b and realization with the bytes of
    its ``K^`` under a key without the closed-loop settings: a change of those tests only the loops whose
    gain is new. The loops still to test, of every b, are tested in one batch.
    """
    A, B = ex.system.A, ex.system.B
    known: dict[int, dict[int, bool]] = {}
    seen: dict[int, dict[int, tuple[bytes, bool]]] = {}
    todo: list[tuple[int, int, np.ndarray]] = []  # (b, realization, gain) not yet tested
    for b in bits:
        loops = ex.closed_loops(b, estimator)
        got = ex.cache.cached({0: ex.keys.own_small_gain(b, estimator)}).get(0, {})
        seen[b] = cast("dict[int, tuple[bytes, bool]]", got)
        known[b] = {}
        for r, K in enumerate(loops.gains):
            if K is None:
                continue
            K = np.ascontiguousarray(K)
            hit = seen[b].get(r)
            if hit is not None and hit[0] == K.tobytes():
                known[b][r] = hit[1]
            else:
                todo.append((b, r, K))
    if todo:
        models = {b: ex.identification(b, estimator) for b in {t[0] for t in todo}}
        holds = small_gain_holds(
            A,
            B,
            np.stack([models[b].A_hat[r] for b, r, _ in todo]),
            np.stack([models[b].B_hat[r] for b, r, _ in todo]),
            np.stack([K for _, _, K in todo]),
        )
        new: dict[int, dict[int, tuple[bytes, bool]]] = {}
        for (b, r, K), h in zip(todo, holds):
            known[b][r] = bool(h)
            new.setdefault(b, {})[r] = (K.tobytes(), bool(h))
        ex.cache.store([(ex.keys.own_small_gain(b, estimator), {**seen[b], **v}) for b, v in new.items()])
    return {b: sum(known[b].values()) for b in bits}


def _theorem1_misfit(row: Mapping[str, Any]) -> str:
    """Empty when the measured mean errors of A^ and B^ are within CERTIFY_TOLERANCE of Theorem 1's, else why."""
    why = []
    hyp = row.get("assumptions") or {}
    if hyp.get("stationary") is False:
        why.append(f"Psi Psi^T / T has no limit (spectral radius of A {hyp.get('spectral_radius', float('nan')):.6g})")
    if hyp.get("known_noise") is False:
        why.append("the dither gives no signal-independent error variance")
    for blk in ("A", "B"):
        meas = (row.get(f"err_{blk}") or {}).get("mean")
        pred = row.get(f"err_{blk}_theory")
        if meas is None or pred is None or not pred > 0:
            why.append(f"no measured or predicted error of {blk}^")
        elif abs(meas - pred) > CERTIFY_TOLERANCE * pred:
            why.append(f"measured err_{blk} {meas:.3g} vs Theorem 1's {pred:.3g} ({meas / pred:.3g}x)")
    return "; ".join(why)


def certificate(
    row: Mapping[str, Any], perturbation: float | None, radius: float | None, realized: int | None, loops: int
) -> tuple[bool | None, str | None, str]:
    """Whether the loops at one b are certified, on what basis, and why (:mod:`qsid_core.studies.bits`).

    Parameters
    ----------
    row : mapping
        The summary row (``err_A``, ``err_B``, ``err_A_theory``, ``err_B_theory``).
    perturbation, radius : float or None
        The small-gain test for Theorem 1's model (:func:`predicted_small_gain`; None: not computed).
    realized : int or None
        Loops certified with their own model error (None: not computed).
    loops : int
        Loops run.

    Returns
    -------
    (certified, basis, note) : bool or None, ``"theorem1"``/``"own-error"``/None, str
    """
    if perturbation is None or radius is None:
        return None, None, ""
    tol = CERTIFY_TOLERANCE
    passes = perturbation * (1 + tol) < radius
    misfit = _theorem1_misfit(row)
    if passes and not misfit:
        return (
            True,
            "theorem1",
            (
                f"certified for Theorem 1's model ({1 + tol:g} x {perturbation:.2g} < {radius:.2g}; measured errors "
                f"within {100 * tol:g} % of it)"
            ),
        )
    if realized is not None and loops and realized == loops:
        return True, "own-error", f"certified for every loop's own model ({realized}/{loops})"
    why = (
        f"small gain fails for Theorem 1's model ({1 + tol:g} x {perturbation:.2g} >= {radius:.2g})"
        if not passes
        else f"large-data hypothesis fails ({misfit}; tolerance {100 * tol:g} %)"
    )
    if realized is not None:
        why += f"; {realized} of {loops} loops certified with their own error"
    return False, None, f"not certified: {why}"
