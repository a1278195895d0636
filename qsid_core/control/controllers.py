"""One MPC controller per identified model, the expensive parts computed for all models at once."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..errors import MPCFailure
from .controller import MPCController
from .mpc import MPCConfig
from .mpc_weights import MPCWeights
from .riccati import LQParts, dare_batch, lq_parts

__all__ = ["build_controllers"]


def build_controllers(
    models: Sequence[tuple[np.ndarray, np.ndarray]],
    w: MPCWeights,
    cfg: MPCConfig,
    failure: list[str],
    messages: list[str],
) -> list[MPCController | None]:
    """One :class:`MPCController` per model (None where it cannot be built; the reason is recorded).

    The expensive parts are computed for all models at once: the terminal weights
    ``Qf`` (stabilizing DARE solutions, by batched doubling; the few it cannot
    settle go to scipy inside MPCController) and the fast-path parts (backward
    Riccati recursion and prediction map, :func:`lq_parts`).
    """
    # models without finite entries (failed identifications) are left to MPCController to reject
    fi = [i for i, (a, b) in enumerate(models) if np.all(np.isfinite(a)) and np.all(np.isfinite(b))]
    Qfs: list[np.ndarray | None] = [w.Qf] * len(models)
    if w.Qf is None and fi:
        X, okd = dare_batch(np.stack([models[i][0] for i in fi]), np.stack([models[i][1] for i in fi]), w.Q, w.R)
        for k, i in enumerate(fi):
            if okd[k]:
                Qfs[i] = X[k]
    ready = [i for i in fi if Qfs[i] is not None]
    parts: dict[int, LQParts] = {}
    if ready:
        with np.errstate(all="ignore"):
            bp = lq_parts(
                np.stack([np.asarray(models[i][0], float) for i in ready]),
                np.stack([np.asarray(models[i][1], float) for i in ready]),
                w.Q,
                w.R,
                np.stack([np.asarray(Qfs[i], float) for i in ready]),
                w.x_ref,
                cfg.horizon,
                w.u_max,
                w.x_max,
                w.xf_max,
            )
        fin = bp.finite()
        parts = {i: bp.model(k) for k, i in enumerate(ready) if fin[k]}
    ctrls: list[MPCController | None] = []
    for i, (Ah, Bh) in enumerate(models):
        try:
            ctrls.append(
                MPCController(
                    Ah,
                    Bh,
                    w.Q,
                    w.R,
                    cfg.horizon,
                    w.u_max,
                    w.x_max,
                    w.xf_max,
                    w.x_ref,
                    Qfs[i],
                    cfg.eps,
                    cfg.max_iter,
                    parts=parts.get(i),
                    solver=cfg.solver,
                )
            )
        except MPCFailure as exc:
            ctrls.append(None)
            failure[i], messages[i] = exc.kind, str(exc)
    return ctrls
