"""The answer to "how many bits?": its rows, its three word lengths and its sentence.

:func:`answer_from_rows` turns a sweep's summary rows into a :class:`BitsAnswer`: per b a
:class:`BitsRow` (stabilized share with its Wilson interval, signed cost gap, certificate, the
letter's bound), then ``b_observed``, ``b_robust`` and ``b_letter`` as defined in
:mod:`qsid_core.studies.bits`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, cast

from ..errors import check_float
from .bits_certificate import certificate
from .bits_cost import cost_gap as row_cost_gap
from .summary import json_clean
from .sweep_result import SweepResult

__all__ = ["BitsRow", "BitsAnswer", "wilson_interval", "from_on", "answer_from_rows", "check_targets"]


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


def from_on(bits: Iterable[int], ok: Iterable[bool]) -> int | None:
    """The smallest b such that ``ok`` holds at it and at every larger b (None if ``ok`` fails at the last)."""
    best: int | None = None
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
        The loops are certified at this b (:mod:`qsid_core.studies.bits`; None without the predicted test).
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
    interval: tuple[float, float]
    cost_gap: float | None
    outcomes: dict[str, int]
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

    def to_dict(self) -> dict[str, Any]:
        return cast(
            "dict[str, Any]",
            json_clean(
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
            ),
        )


@dataclass(frozen=True)
class BitsAnswer:
    """The answer to "how many bits?" (:mod:`qsid_core.studies.bits` defines the three word lengths).

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
        (:func:`qsid_core.control.controllability.data_rate_bits`); a different question from the
        word length of the training data, given for comparison.
    loop_length : dict or None
        ``{"steps": N, "rule": text}``: the closed-loop length the costs were measured over
        and how it was chosen (:func:`qsid_core.studies.bits_cost.loop_length`).
    """

    system: str
    settings: dict[str, Any]
    b_observed: int | None
    b_robust: int | None
    b_letter: int | None
    rows: tuple[Any, ...]  # BitsRow; app.figures.bits_needed does not yet type-check against BitsRow
    true_cost: float | None = None
    data_rate_bits: float | None = None
    loop_length: dict[str, Any] | None = None
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

    def to_dict(self) -> dict[str, Any]:
        return cast(
            "dict[str, Any]",
            json_clean(
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
            ),
        )


def check_targets(target: float, cost_gap: float) -> tuple[float, float]:
    """``(target, cost_gap)`` checked: ``target`` in (0, 1], ``cost_gap`` in [0, 1e6] (ConfigError naming the field)."""
    target = check_float("target", target, 0.0, 1.0, lo_open=True)
    cost_gap = check_float("cost gap", cost_gap, 0.0, 1e6)
    return target, cost_gap


def _bits_row(
    r: Mapping[str, Any],
    true_cost: float | None,
    robust: Mapping[int, tuple[float, float]] | None,
    robust_realized: Mapping[int, int] | None,
) -> BitsRow:
    """One summary row as a :class:`BitsRow`: stabilized share, cost gap, certificate, the letter's bound."""
    b = int(r["bits"])
    oc = r.get("closed_loop_outcomes") or {}
    total = sum(oc.values())
    pert, rad = (robust or {}).get(b, (None, None))
    realized = (robust_realized or {}).get(b)
    ok, basis, note = certificate(r, pert, rad, realized, total)
    return BitsRow(
        bits=b,
        stabilized_fraction=oc["converged"] / total if total else None,
        interval=wilson_interval(oc.get("converged", 0), total),
        cost_gap=row_cost_gap(r, true_cost),
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


def _word_lengths(
    rows: Sequence[BitsRow], target: float, cost_gap: float, robust: bool
) -> tuple[int | None, int | None, int | None]:
    """``(b_observed, b_robust, b_letter)`` of rows sorted by b (``b_robust`` None without the predicted test)."""
    bits = [r.bits for r in rows]
    b_obs = from_on(
        bits,
        [
            r.stabilized_fraction is not None
            and r.stabilized_fraction >= target - 1e-12
            and r.cost_gap is not None
            and abs(r.cost_gap) <= cost_gap
            for r in rows
        ],
    )
    b_rob = from_on(bits, [bool(r.robust) for r in rows]) if robust else None
    b_let = from_on(bits, [bool(r.bound_self_consistent) and bool(r.bound_informative) for r in rows])
    return b_obs, b_rob, b_let


def answer_from_rows(
    system: str,
    settings: dict[str, Any],
    rows: Sequence[Mapping[str, Any]],
    true_cost: float | None,
    *,
    robust: dict[int, tuple[float, float]] | None = None,
    robust_realized: dict[int, int] | None = None,
    target: float = 0.95,
    cost_gap: float = 0.01,
    data_rate: float | None = None,
    loop_length: dict[str, Any] | None = None,
) -> BitsAnswer:
    """The answer from a sweep's summary rows (``SummaryRow`` or their dicts), as the dashboard has them.

    Parameters
    ----------
    system : str
    settings : dict
        The sweep's configuration; ``target`` and ``cost_gap`` are added.
    rows : sequence of mapping, one per b
        One summary row per b (keys of :class:`qsid_core.studies.summary.SummaryRow`).
    true_cost : float or None
    robust : dict b -> (perturbation, radius), optional
        The predicted small-gain test per b (:func:`qsid_core.studies.bits_certificate.predicted_small_gain`);
        without it ``b_robust`` is None.
    robust_realized : dict b -> int, optional
    target, cost_gap : float
        ``target`` in (0, 1]; ``cost_gap`` >= 0 (relative).
    data_rate : float, optional
        The plant's data-rate floor (:func:`qsid_core.control.controllability.data_rate_bits`).
    loop_length : dict, optional
        How long the loops ran (:func:`qsid_core.studies.bits_cost.loop_length`).
    """
    target, cost_gap = check_targets(target, cost_gap)
    out = tuple(_bits_row(r, true_cost, robust, robust_realized) for r in sorted(rows, key=lambda r: r["bits"]))
    b_obs, b_rob, b_let = _word_lengths(out, target, cost_gap, bool(robust))
    return BitsAnswer(
        system,
        {**settings, "target": target, "cost_gap": cost_gap},
        b_obs,
        b_rob,
        b_let,
        out,
        true_cost,
        data_rate,
        loop_length,
    )
