"""How many bits does the controller need? Three word lengths from one sweep.

For each b of a sweep: the share of closed loops that converge on the true plant
(:mod:`qsid_core.control.verdicts`) with a 95 % Wilson interval, and the gap of the
mean closed-loop cost to the MPC built on the true model. From those rows:

``b_observed``
    The smallest b from which on (every larger b of the sweep too) at least
    ``target`` of the loops are stabilized and the mean cost gap is at most
    ``cost_gap`` in absolute value.
``b_robust``
    The smallest b from which on a *sufficient* condition certifies the loops.
    With ``(A^, B^)`` a model and ``K^`` the gain of the MPC built on it (its
    unconstrained law), the small-gain theorem gives stability of ``A - B K^`` when
    ``||(A - A^) - (B - B^) K^||_2 < r_C(A^ - B^ K^)``, the complex stability radius of the
    nominal loop (:func:`qsid_core.control.stability.small_gain_margin`). A b is certified

    * for **Theorem 1's model** (its large-data limit of LS at that b) when the test
      holds with the margin :data:`CERTIFY_TOLERANCE` (``(1 + tol) ||.|| < r_C``) *and* its
      hypotheses are checked on the data: the data's second moments have a limit and the
      dither a known error variance (:mod:`qsid_core.studies.assumptions`), and the
      measured mean relative errors of A^ and B^ are both within ``CERTIFY_TOLERANCE``
      (25 %) of Theorem 1's (in finite data,
      where the fluctuation dominates, or with BCLS, they are not, and a certificate
      for a model the data do not give would be no certificate); or
    * for **every loop's own model**: the test holds for each realization's model and
      gain (no large-data hypothesis; ``robust_realized`` equals the loops run).

    Otherwise the row says "not certified: <why, with the numbers>". Both assume the
    constraints inactive near the reference (the MPC is its linear law there).
``b_letter``
    The smallest b from which on the letter's ultimate bound is self-consistent
    (``delta < rho``: its proof assumes the state stays within ``rho``) and
    informative (``delta < ||x0||``).

Each is None when no b of the sweep qualifies.
"""

from __future__ import annotations

import dataclasses
import math
from concurrent.futures import Executor
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np

from ..control.stability import data_rate_bits
from ..errors import ConfigError, check_float
from .config import SweepConfig
from .experiment import Experiment, Progress
from .summary import json_clean
from .sweep import run_sweep
from .sweep_result import SweepResult

__all__ = [
    "CERTIFY_TOLERANCE",
    "LOOP_COST_TOLERANCE",
    "LOOP_TIME_CONSTANTS",
    "loop_length",
    "certificate",
    "BitsRow",
    "BitsAnswer",
    "wilson_interval",
    "from_on",
    "predicted_small_gain",
    "realized_small_gain",
    "bits_needed",
    "answer_from_rows",
]


#: b_robust through Theorem 1's model needs the measured errors within this relative distance of the
#: prediction, and the small-gain test to hold with this margin.
CERTIFY_TOLERANCE = 0.25
#: The loop length chosen from the plant: the true-model loop's cost after it is at most this share of its total.
LOOP_COST_TOLERANCE = 1e-6
#: ... searched over this many slowest time constants of the true-model loop (at most 10000 steps).
LOOP_TIME_CONSTANTS = 20


def wilson_interval(k: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """95 % Wilson score interval of a proportion ``k / n`` (``(nan, nan)`` when ``n == 0``)."""
    if n <= 0:
        return float("nan"), float("nan")
    p = k / n
    d = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / d
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    lo, hi = max(0.0, centre - half), min(1.0, centre + half)
    return (0.0 if k == 0 else lo), (1.0 if k == n else hi)  # exact at the ends (no rounding below 1)


def from_on(bits, ok) -> int | None:
    """The smallest b such that ``ok`` holds at it and at every larger b (None if ``ok`` fails at the last)."""
    best = None
    for b, good in sorted(zip(bits, ok), reverse=True):
        if not good:
            break
        best = b
    return best


@dataclass(frozen=True)
class BitsRow:
    """One word length of the answer.

    Attributes
    ----------
    bits : int
    stabilized_fraction : float or None
        Loops judged ``converged`` / loops run (None without verdicts).
    interval : tuple of float
        Its 95 % Wilson interval over the realizations.
    cost_gap : float or None
        ``mean closed-loop cost / true-model cost - 1``, signed, over the loops judged converged
        or bounded (None when none is: every loop diverged or failed, see ``diverged``).
    outcomes : dict
        ``{"converged", "bounded", "diverged", "failed"}`` counts.
    robust : bool or None
        The loops are certified at this b (module docstring; None without the predicted test).
    robust_perturbation, robust_radius : float or None
        ``||dA - dB K^||_2`` and ``r_C(A^ - B^ K^)`` of the test for Theorem 1's model.
    robust_realized : int or None
        Realizations certified by the same test with their *own* model error.
    robust_basis : str or None
        ``"theorem1"`` or ``"own-error"``: what certified it (None: not certified).
    robust_note : str
        Why it is certified, or "not certified: ..." with the hypothesis that fails and its numbers.
    delta, rho : float or None
        The letter's ultimate bound and the ``rho`` it used.
    bound_self_consistent, bound_informative : bool or None
    """

    bits: int
    stabilized_fraction: float | None
    interval: tuple
    cost_gap: float | None
    outcomes: dict
    robust: bool | None = None
    robust_perturbation: float | None = None
    robust_radius: float | None = None
    robust_realized: int | None = None
    delta: float | None = None
    rho: float | None = None
    bound_self_consistent: bool | None = None
    bound_informative: bool | None = None
    robust_basis: str | None = None
    robust_note: str = ""

    @property
    def diverged(self) -> bool:
        """Every loop that ran diverged or failed: no cost to compare."""
        return self.cost_gap is None and sum(self.outcomes.values()) > 0

    def to_dict(self) -> dict:
        return json_clean(
            {
                "bits": self.bits,
                "stabilized_fraction": self.stabilized_fraction,
                "stabilized_interval": list(self.interval),
                "cost_gap": self.cost_gap,
                "cost_gap_abs": None if self.cost_gap is None else abs(self.cost_gap),
                "cost_diverged": self.diverged,
                "closed_loop_outcomes": self.outcomes,
                "robust_certified": self.robust,
                "robust_basis": self.robust_basis,
                "robust_note": self.robust_note,
                "robust_perturbation": self.robust_perturbation,
                "robust_radius": self.robust_radius,
                "robust_certified_realized": self.robust_realized,
                "ultimate_bound": self.delta,
                "rho": self.rho,
                "bound_self_consistent": self.bound_self_consistent,
                "bound_informative": self.bound_informative,
            }
        )


@dataclass(frozen=True)
class BitsAnswer:
    """The answer to "how many bits?" (see the module docstring for the three word lengths).

    Attributes
    ----------
    system : str
    settings : dict
        The sweep's configuration (as in ``SweepResult.to_dict()["config"]``) plus ``target`` and ``cost_gap``.
    b_observed, b_robust, b_letter : int or None
    rows : tuple of BitsRow
    true_cost : float or None
        Closed-loop cost of the MPC built on the true model.
    data_rate_bits : float or None
        The data-rate theorem's floor for *quantized feedback* of this plant
        (:func:`qsid_core.control.stability.data_rate_bits`); a different question from the
        word length of the training data, given for comparison.
    loop_length : dict or None
        ``{"steps": N, "rule": text}``: the closed-loop length the costs were measured over
        and how it was chosen (:func:`loop_length`).
    """

    system: str
    settings: dict
    b_observed: int | None
    b_robust: int | None
    b_letter: int | None
    rows: tuple
    true_cost: float | None = None
    data_rate_bits: float | None = None
    loop_length: dict | None = None
    result: SweepResult | None = field(default=None, repr=False, compare=False)

    @property
    def sentence(self) -> str:
        """The answer in one sentence."""
        t, g = self.settings.get("target", 0.95), self.settings.get("cost_gap", 0.01)
        bits = [r.bits for r in self.rows]
        span = f"b = {bits[0]}..{bits[-1]}" if len(bits) > 1 else f"b = {bits[0]}"
        if self.b_observed is None:
            obs = (
                f"in {span} the MPC does not stabilize {100 * t:g} % of the loops with a cost within "
                f"{100 * g:g} % of the true model's up to the last b"
            )
        else:
            obs = (
                f"the MPC stabilizes at least {100 * t:g} % of the loops, with a cost within {100 * g:g} % of "
                f"the true model's, from b = {self.b_observed} on"
            )
        rob = self._robust_words()
        let = (
            "the letter's bound says nothing up to the last b"
            if self.b_letter is None
            else f"the letter's bound says something from b = {self.b_letter}"
        )
        dr = ""
        if self.data_rate_bits and self.data_rate_bits >= 0.005:
            dr = (
                f" (Quantized feedback of this plant would need more than {self.data_rate_bits:.2f} bits per "
                "sample: the data-rate theorem.)"
            )
        return f"{obs}; {rob}; {let}.{dr}"

    def _robust_words(self) -> str:
        if self.b_robust is not None:
            row = next(r for r in self.rows if r.bits == self.b_robust)
            how = "Theorem 1's model" if row.robust_basis == "theorem1" else "every loop's own model"
            return f"the small-gain certificate holds from b = {self.b_robust} on (at b = {self.b_robust}: {how})"
        judged = [r for r in self.rows if r.robust is not None]
        if not judged:
            return "the small-gain certificate was not computed"
        last = judged[-1]
        return f"the small-gain certificate is not given (at b = {last.bits}, {last.robust_note})"

    def to_dict(self) -> dict:
        return json_clean(
            {
                "system": self.system,
                "settings": self.settings,
                "b_observed": self.b_observed,
                "b_robust": self.b_robust,
                "b_letter": self.b_letter,
                "true_model_cost": self.true_cost,
                "data_rate_bits": self.data_rate_bits,
                "loop_length": self.loop_length,
                "sentence": self.sentence,
                "rows": [r.to_dict() for r in self.rows],
            }
        )


def _check_targets(target: float, cost_gap: float) -> tuple[float, float]:
    target = check_float("target", target, 0.0, 1.0, lo_open=True)
    cost_gap = check_float("cost gap", cost_gap, 0.0, 1e6)
    return target, cost_gap


def predicted_small_gain(ex: Experiment, b: int) -> tuple[float, float]:
    """``(perturbation, radius)`` of the small-gain test for Theorem 1's predicted model at ``b``.

    ``K^`` is the first gain of the MPC's Riccati recursion on the predicted model
    (its terminal weight: the configured ``Qf`` or the model's DARE solution).
    ``(inf, 0)`` when no MPC can be built on that model. Cached in ``ex``.
    """
    from ..control.mpc import MPCConfig
    from ..control.riccati import dare_stabilizing, lq_parts
    from ..control.stability import small_gain_margin
    from ..errors import MPCFailure

    mcfg = ex.config.mpc or MPCConfig()
    th = ex.theory(b)
    k = ex.keys.small_gain(b, th.G_pred)
    try:
        return cast("tuple[float, float]", ex.cache.mapping[k])
    except KeyError:  # (a shared, bounded cache may also have dropped it: computed again)
        pass
    sysm = ex.system
    n = sysm.n
    w = mcfg.resolve(sysm)
    Ah, Bh = th.G_pred[:, :n], th.G_pred[:, n:]
    try:
        Qf = w.Qf if w.Qf is not None else dare_stabilizing(Ah, Bh, w.Q, w.R)
        with np.errstate(all="ignore"):
            parts = lq_parts(
                Ah[None], Bh[None], w.Q, w.R, np.asarray(Qf)[None], np.zeros(n), mcfg.horizon, w.u_max, None, None
            )
        K = parts.K[0, 0]
        res = small_gain_margin(sysm.A, sysm.B, Ah, Bh, K) if np.all(np.isfinite(K)) else (math.inf, 0.0)
    except (MPCFailure, np.linalg.LinAlgError):
        res = (math.inf, 0.0)
    ex.cache.store([(k, res)])
    return res


def realized_small_gain(ident, loops, A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Per realization: whether the small-gain test certifies its loop with its *own* model error.

    ``K^`` is read from the loop's unconstrained law (``A - B K^`` has the loop's
    spectral radius). A sufficient condition: every certified loop has spectral
    radius below 1 (tested), not the other way round.

    Returns
    -------
    ndarray of bool, shape (R,) (False where the loop has no MPC).
    """
    from ..control.stability import small_gain_holds

    out = np.zeros(len(ident.err_A), dtype=bool)
    idx = [r for r, K in enumerate(loops.gains) if K is not None]
    if idx:
        out[idx] = small_gain_holds(A, B, ident.A_hat[idx], ident.B_hat[idx], np.stack([loops.gains[r] for r in idx]))
    return out


def answer_from_rows(
    system: str,
    settings: dict,
    rows: list,
    true_cost: float | None,
    *,
    robust: dict | None = None,
    robust_realized: dict | None = None,
    target: float = 0.95,
    cost_gap: float = 0.01,
    data_rate: float | None = None,
    loop_length: dict | None = None,
) -> BitsAnswer:
    """The answer from a sweep's summary rows (``SummaryRow`` or their dicts), as the dashboard has them.

    Parameters
    ----------
    rows : list of mapping
        One summary row per b (keys of :class:`qsid_core.studies.summary.SummaryRow`).
    true_cost : float or None
    robust : dict b -> (perturbation, radius), optional
        The predicted small-gain test per b (:func:`predicted_small_gain`); without it ``b_robust`` is None.
    robust_realized : dict b -> int, optional
    target, cost_gap : float
        ``target`` in (0, 1]; ``cost_gap`` >= 0 (relative).
    data_rate : float, optional
        The plant's data-rate floor (:func:`qsid_core.control.stability.data_rate_bits`).
    loop_length : dict, optional
        How long the loops ran (:func:`loop_length`).
    """
    target, cost_gap = _check_targets(target, cost_gap)
    out = []
    for r in sorted(rows, key=lambda r: r["bits"]):
        b = int(r["bits"])
        oc = r.get("closed_loop_outcomes") or {}
        total = sum(oc.values())
        frac = oc["converged"] / total if total else None
        mc = r.get("mpc_cost") or {}
        if "mean_bounded" in mc:
            cost = mc["mean_bounded"]
        else:  # rows without it (older results): the plain mean, only when no loop diverged or failed
            cost = mc.get("mean") if not (oc.get("diverged") or oc.get("failed")) else None
        gap = (cost / true_cost - 1.0) if (cost is not None and true_cost) else None
        pert, rad = (robust or {}).get(b, (None, None))
        realized = (robust_realized or {}).get(b)
        ok, basis, note = certificate(r, pert, rad, realized, total)
        out.append(
            BitsRow(
                bits=b,
                stabilized_fraction=frac,
                interval=wilson_interval(oc.get("converged", 0), total),
                cost_gap=gap,
                outcomes=dict(oc),
                robust=ok,
                robust_perturbation=pert,
                robust_radius=rad,
                robust_realized=realized,
                delta=r.get("ultimate_bound"),
                rho=r.get("rho"),
                bound_self_consistent=r.get("bound_self_consistent"),
                bound_informative=r.get("bound_informative"),
                robust_basis=basis,
                robust_note=note,
            )
        )
    bits = [r.bits for r in out]
    b_obs = from_on(
        bits,
        [
            r.stabilized_fraction is not None
            and r.stabilized_fraction >= target - 1e-12
            and r.cost_gap is not None
            and abs(r.cost_gap) <= cost_gap
            for r in out
        ],
    )
    b_rob = from_on(bits, [bool(r.robust) for r in out]) if robust else None
    b_let = from_on(bits, [bool(r.bound_self_consistent) and bool(r.bound_informative) for r in out])
    return BitsAnswer(
        system,
        {**settings, "target": target, "cost_gap": cost_gap},
        b_obs,
        b_rob,
        b_let,
        tuple(out),
        true_cost,
        data_rate,
        loop_length,
    )


def _theorem1_misfit(row) -> str:
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
    row, perturbation: float | None, radius: float | None, realized: int | None, loops: int
) -> tuple[bool | None, str | None, str]:
    """Whether the loops at one b are certified, on what basis, and why (see the module docstring).

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


def loop_length(ex: Experiment) -> dict[str, Any]:
    """The closed-loop length chosen from the plant: ``{"steps": N, "rule": text}``.

    The MPC built on the true model is run for :data:`LOOP_TIME_CONSTANTS` slowest time constants
    of its linear law (``-1 / ln rho(A - B K)`` steps, at most 10000); ``N`` is the first step
    after which its remaining cost is at most :data:`LOOP_COST_TOLERANCE` of its total, so the
    cost gap is not an artefact of stopping early. Kept as configured, with the reason, when the
    true-model loop cannot settle (a disturbance, sensor noise, a quantized measurement, a
    time-varying reference, or the true-model loop itself not converging).
    """
    cfg = ex.config.mpc
    if cfg is None:
        raise ConfigError("the loop length needs the MPC (mpc must not be None)")
    if cfg.disturbance or cfg.feedback_noise or cfg.feedback_bits is not None or cfg.reference is not None:
        return {"steps": cfg.steps, "rule": f"{cfg.steps} steps as configured (the loop does not settle to a point)"}
    radii = ex.true_model_loop().spectral_radius
    rho = float(radii[0]) if radii is not None else math.nan
    if not (0.0 <= rho < 1.0):
        return {"steps": cfg.steps, "rule": f"{cfg.steps} steps as configured (the true-model loop is not stable)"}
    tau = -1.0 / math.log(rho) if rho > 0 else 1.0
    scan = int(min(10000, max(cfg.horizon, math.ceil(LOOP_TIME_CONSTANTS * tau))))
    lp = ex.with_config(dataclasses.replace(ex.config, mpc=dataclasses.replace(cfg, steps=scan))).true_model_loop()
    w = cfg.resolve(ex.system)
    e = lp.states[0, :-1] - np.asarray(lp.x_ref, dtype=float).reshape(-1, ex.system.n)[:scan]
    u = lp.inputs[0]
    stage = np.einsum("ti,ij,tj->t", e, w.Q, e) + np.einsum("ti,ij,tj->t", u, w.R, u)
    if not np.all(np.isfinite(stage)) or not stage.sum() > 0:
        return {"steps": cfg.steps, "rule": f"{cfg.steps} steps as configured (the true-model cost is not finite)"}
    tail = np.cumsum(stage[::-1])[::-1]  # tail[t]: cost from step t on
    steps = int(np.argmax(tail <= LOOP_COST_TOLERANCE * tail[0])) if tail[-1] <= LOOP_COST_TOLERANCE * tail[0] else scan
    steps = max(steps, 1)
    return {
        "steps": steps,
        "rule": f"{steps} steps: the true-model loop's remaining cost is below {LOOP_COST_TOLERANCE:g} of its total "
        f"(slowest time constant {tau:.3g} steps; searched over {scan})",
    }


def bits_needed(
    config: SweepConfig,
    *,
    target: float = 0.95,
    cost_gap: float = 0.01,
    executor: Executor | None = None,
    progress: Progress | None = None,
    experiment: Experiment | None = None,
    realized: bool = True,
    auto_length: bool = False,
) -> BitsAnswer:
    """Run the sweep of ``config`` and answer "how many bits?" (see the module docstring).

    Parameters
    ----------
    config : SweepConfig
        Needs MPC on (``config.mpc`` not None) and the verdicts (``mpc.verify_steps`` not None).
    target : float in (0, 1]
        Share of stabilized loops ``b_observed`` asks for (default 0.95).
    cost_gap : float >= 0
        Largest relative gap of the mean cost to the true model's (default 0.01).
    executor, progress, experiment
        As in :func:`qsid_core.studies.sweep.run_sweep`.
    realized : bool
        Also count per b the realizations the small-gain test certifies with their own error
        (without it, only Theorem 1's model can certify a b).
    auto_length : bool
        Run the loops for the length chosen from the plant (:func:`loop_length`) instead of
        ``config.mpc.steps``.

    Raises
    ------
    ConfigError
        Bad ``target``/``cost_gap``, MPC off, or verdicts off.
    """
    target, cost_gap = _check_targets(target, cost_gap)
    if config.mpc is None:
        raise ConfigError("bits needs the MPC closed loops (mpc must not be None)")
    if config.mpc.verify_steps is None:
        raise ConfigError("bits needs the closed-loop verdicts (verify_steps must not be None)")
    ex = experiment.with_config(config) if experiment is not None else Experiment(config, executor)
    if executor is not None:
        ex.executor = executor
    length: dict[str, Any] = (
        loop_length(ex)
        if auto_length
        else {"steps": config.mpc.steps, "rule": f"{config.mpc.steps} steps as configured"}
    )
    if int(length["steps"]) != config.mpc.steps:
        config = dataclasses.replace(config, mpc=dataclasses.replace(config.mpc, steps=int(length["steps"])))
        ex = ex.with_config(config)
    res = run_sweep(config, executor=executor, progress=progress, experiment=ex)
    robust = {b: predicted_small_gain(ex, b) for b in res.bits}
    rr = None
    if realized:
        rr = {
            b: int(realized_small_gain(res.identification[b], res.loops[b], res.system.A, res.system.B).sum())
            for b in res.bits
        }
    true_cost = float(res.true_loop.cost[0]) if res.true_loop is not None else None
    settings = res.to_dict()["config"]
    ans = answer_from_rows(
        res.system.name,
        settings,
        [res.summary(b) for b in res.bits],
        true_cost,
        robust=robust,
        robust_realized=rr,
        target=target,
        cost_gap=cost_gap,
        data_rate=data_rate_bits(res.system.A),
        loop_length=length,
    )
    return dataclasses.replace(ans, result=res)
