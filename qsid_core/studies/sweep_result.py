"""A finished sweep, :class:`SweepResult` (per-b summaries, per-realization arrays, tables, pandas), its JSON
layout (:data:`RESULT_FORMAT`) and :func:`load_result`, which reads a saved one back."""

from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from functools import partial
from typing import TYPE_CHECKING, Any

import numpy as np

from ..control.controllability import data_rate_bits
from ..control.loop_results import ClosedLoops
from ..errors import ConfigError
from ..plant.lti import LTISystem
from ..quantization.quantize import ERROR_VARIANCE, NOMINAL_VARIANCE, bcls_reason
from ..version import __version__
from .config import SweepConfig
from .stage_results import BitsIdentification, TheoryAtBits
from .summary import UNKNOWN, SummaryRow, json_clean, summary_row

if TYPE_CHECKING:
    from ..control.realized_bound import RealizedBounds
    from .assumptions import Assumptions

__all__ = ["RESULT_FORMAT", "StoredRow", "SweepResult", "load_result"]

#: Version of the sweep result's JSON layout (the ``result_format`` key). 1: files without the key, whose
#: rows count the closed-loop steps that needed the QP solver as ``osqp_steps``; 2: that key is ``qp_steps``.
RESULT_FORMAT = 2


@dataclass
class SweepResult:
    """A finished sweep: per-b summaries plus per-realization arrays.

    Attributes
    ----------
    config : SweepConfig
    bits : tuple of int
    identification : dict b -> BitsIdentification
    theory : dict b -> TheoryAtBits
    loops : dict b -> ClosedLoops (empty when MPC is off)
    true_loop : ClosedLoops or None
    slope_A, slope_B : float
        LS slope of log10(mean relative error) against b.
    timing_s : dict
        Wall-clock seconds per stage.
    realized : dict b -> RealizedBounds
        A-posteriori ultimate bounds (each realization's own model error and P).
    assumptions : dict b -> Assumptions
        Hypotheses of Theorem 1 and BCLS per b.
    rows : dict b -> StoredRow
        The per-b summaries of a result read back by :func:`load_result` (empty for a fresh sweep).
    version : str
        The qsid version that made a loaded result ("" for a fresh one: this version).
    ranges : dict or None
        The quantizer's data ranges ``{"lo": [...], "hi": [...]}`` (n + m channels).
    true_cost : float or None
        A loaded result's true-model MPC cost.
    true_errors : dict
        A loaded result's true-model ``steady_state_error`` and ``tracking_error``.
    """

    config: SweepConfig
    system: LTISystem
    bits: tuple[int, ...]
    identification: dict[int, BitsIdentification]
    theory: dict[int, TheoryAtBits]
    loops: dict[int, ClosedLoops]
    true_loop: ClosedLoops | None
    slope_A: float
    slope_B: float
    timing_s: dict[str, float]
    realized: dict[int, RealizedBounds] = field(default_factory=dict)
    assumptions: dict[int, Assumptions] = field(default_factory=dict)

    rows: dict[int, StoredRow] = field(default_factory=dict)
    version: str = ""
    ranges: dict[str, list[float]] | None = None
    true_cost: float | None = None
    true_errors: dict[str, float | None] = field(default_factory=dict)

    def _check_bits(self, b: object) -> int:
        if isinstance(b, bool) or not isinstance(b, (int, np.integer)) or int(b) not in self.bits:
            swept = ", ".join(map(str, self.bits))
            raise ConfigError(f"b = {b!r} was not swept; this result has b = {swept}")
        return int(b)

    def summary(self, b: int) -> SummaryRow | StoredRow:
        """The typed summary at word length ``b``; ``.to_dict()`` is the CLI's ``results`` entry.

        A result read back by :func:`load_result` returns its stored row (a :class:`StoredRow`).

        Raises
        ------
        ConfigError
            If ``b`` was not swept (the message lists the swept b).
        """
        b = self._check_bits(b)
        if b not in self.identification:
            return self.rows[b]
        lp = self.loops.get(b)
        u_max = self.config.mpc.resolve(self.system).u_max if (lp is not None and self.config.mpc) else UNKNOWN
        return summary_row(
            self.system.n,
            self.identification[b],
            self.theory[b],
            lp,
            u_max=u_max,
            realized=self.realized.get(b),
            assumptions=self.assumptions.get(b),
        )

    def to_dict(self) -> dict[str, Any]:
        """The whole sweep as strict JSON data (NaN and inf become None).

        ``config`` holds every setting (:meth:`SweepConfig.to_dict`: the full system, the MPC
        settings, seeds) so that ``SweepConfig.from_dict`` / ``qsid sweep --config`` re-run it;
        ``qsid_version`` says which qsid made it and ``ranges`` the quantizer's data ranges.
        """
        c = self.config
        q = c.quantizer
        cfg = c.to_dict(self.system)
        cfg["mpc"] = (
            None
            if c.mpc is None
            else {
                "horizon": c.mpc.horizon,
                "steps": c.mpc.steps,
                "u_max": list(c.mpc.u_max),
                "disturbance": c.mpc.disturbance,
                "disturbance_kind": c.mpc.disturbance_kind,
                "feedback_bits": c.mpc.feedback_bits,
                "feedback_noise": c.mpc.feedback_noise,
                "loop_seed": c.mpc.loop_seed,
                "tracking": c.mpc.tracking,
                "reference": c.mpc.reference
                if isinstance(c.mpc.reference, (str, type(None)))
                else [list(r) for r in c.mpc.reference],
            }
        )
        why = bcls_reason(q.dither)
        out: dict[str, Any] = json_clean(
            {
                "result_format": RESULT_FORMAT,
                "qsid_version": self.version or __version__,
                "system": self.system.name,
                "config": cfg,
                "ranges": self.ranges,
                "bcls": {
                    "applicable": not why,
                    "reason": why,
                    "D": f"eps^2/{round(1 / ERROR_VARIANCE.get(q.dither, NOMINAL_VARIANCE))}"
                    + (" (nominal)" if why else "")
                    + (" + sigma^2 (sensor noise)" if c.noise_known and any(v > 0 for v in c.noise) else ""),
                },
                "results": [self.summary(b).to_dict() for b in self.bits],
                "mpc_cost_true_model": self.true_cost if self.true_loop is None else float(self.true_loop.cost[0]),
                "steady_state_error_true_model": self.true_errors.get("steady_state_error")
                if self.true_loop is None
                else float(self.true_loop.steady_state_error[0]),
                "tracking_error_true_model": self.true_errors.get("tracking_error")
                if self.true_loop is None
                else float(self.true_loop.tracking_error[0]),
                "data_rate_bits": data_rate_bits(self.system.A),
                "slope_A": float(self.slope_A),
                "slope_B": float(self.slope_B),
                "timing_s": self.timing_s,
            }
        )
        return out

    # ----- notebooks ---------------------------------------------------------------------------
    def _table(self) -> tuple[list[str], list[list[Any]]]:
        head = [
            "b",
            "estimator",
            "err_A mean",
            "err_A std",
            "err_B mean",
            "err_B std",
            "Thm1 A",
            "Thm1 B",
            "overload",
            "delta",
        ]
        out = []
        for b in self.bits:
            r = self.summary(b).to_dict()
            out.append(
                [
                    b,
                    self.config.estimator,
                    r["err_A"]["mean"],
                    r["err_A"]["std"],
                    r["err_B"]["mean"],
                    r["err_B"]["std"],
                    r["err_A_theory"],
                    r["err_B_theory"],
                    r["overload_fraction"],
                    r["ultimate_bound"],
                ]
            )
        return head, out

    def _title(self) -> str:
        c, q = self.config, self.config.quantizer
        ib = "" if c.input_bits is None else f", input bits {c.input_bits}"
        ib += "" if c.state_bits is None else f", state bits {','.join(map(str, c.state_bits))}"
        return (
            f"SweepResult: {self.system.name} ({self.system.n} states, {self.system.m} inputs), "
            f"b = {_bits_text(self.bits)}{ib}, {c.realizations} realizations, {c.trajectories} x {c.steps}, "
            f"dither {q.dither}, estimator {c.estimator}"
            + (", MPC off" if c.mpc is None else "")
            + (" (loaded: summaries only)" if self.rows and not self.identification else "")
        )

    def __repr__(self) -> str:
        """A few lines: the settings and one row per b (at most 12 rows; never the arrays)."""
        head, rows = self._table()
        fmt = partial(_cell, digits=3)
        shown = rows if len(rows) <= 12 else rows[:6] + [["..."] * len(head)] + rows[-5:]
        lines = [self._title(), "  " + "  ".join(head)]
        lines += ["  " + "  ".join(fmt(v) for v in r) for r in shown]
        lines.append(
            f"  slope per bit: A {self.slope_A:+.3f}, B {self.slope_B:+.3f}; .to_frame(), .summary(b), .to_dict()"
        )
        return "\n".join(lines)[:2000]

    def _repr_html_(self) -> str:
        """An HTML table for notebooks (one row per b)."""
        import html

        head, rows = self._table()
        fmt = partial(_cell, digits=4)
        th = "".join(f"<th>{html.escape(h)}</th>" for h in head)
        body = "".join("<tr>" + "".join(f"<td>{html.escape(fmt(v))}</td>" for v in r) + "</tr>" for r in rows)
        return (
            f"<div><p>{html.escape(self._title())}</p><table><thead><tr>{th}</tr></thead>"
            f"<tbody>{body}</tbody></table></div>"
        )

    def to_frame(self, pandas: bool = True) -> Any:
        """One row per b and estimator: errors (mean, std), Theorem 1, overload, bound, MPC cost.

        Parameters
        ----------
        pandas : bool
            True: a ``pandas.DataFrame`` (raises ImportError with advice when pandas is missing);
            False: a dict of equal-length column lists.
        """
        head, rows = self._table()
        cols = {h.replace(" ", "_"): [r[i] for r in rows] for i, h in enumerate(head)}
        cols["mpc_cost_mean"] = [(self.summary(b).to_dict().get("mpc_cost") or {}).get("mean") for b in self.bits]
        if not pandas:
            return cols
        try:
            import pandas as pd
        except ImportError as exc:
            raise ImportError(
                "to_frame() needs pandas (pip install pandas); to_frame(pandas=False) gives plain column lists"
            ) from exc
        return pd.DataFrame(cols)


class StoredRow(dict[str, Any]):
    """A per-b summary read back from JSON (:func:`load_result`): a mapping with ``to_dict()``."""

    def to_dict(self) -> dict[str, Any]:
        """The row as a plain dict."""
        return dict(self)


def _cell(v: object, digits: int) -> str:
    """A table cell: "-" for None, floats to ``digits`` significant digits."""
    return "-" if v is None else (f"{v:.{digits}g}" if isinstance(v, float) else str(v))


def _bits_text(bits: Iterable[int]) -> str:
    b = list(bits)
    if len(b) > 2 and b == list(range(b[0], b[-1] + 1)):
        return f"{b[0]}..{b[-1]}"
    return ",".join(map(str, b))


def _upgrade_row(row: dict[str, Any], fmt: int) -> dict[str, Any]:
    """A per-b summary of JSON format ``fmt`` in the current format's keys (same order)."""
    if fmt < 2:
        row = {("qp_steps" if k == "osqp_steps" else k): v for k, v in row.items()}
    return row


def load_result(path: str | os.PathLike[str]) -> SweepResult:
    """Read a saved sweep (``qsid sweep --out FILE`` or ``json.dump(res.to_dict())``) back into a SweepResult.

    The result has the full config and system (so ``run_sweep(res.config)`` re-runs it to the
    same numbers), the per-b summaries (:meth:`SweepResult.summary`, ``to_frame``, ``to_dict``),
    slopes and timing; per-realization arrays are not in the JSON (``identification`` etc. are
    empty).

    Raises
    ------
    ConfigError
        If the file is missing, not JSON, or not a sweep result with a full config (files
        written before the config carried the system are refused with that reason), or its
        ``result_format`` is newer than :data:`RESULT_FORMAT`. Older formats are read and their
        rows renamed to the current keys (format 1's ``osqp_steps`` becomes ``qp_steps``).
    """
    import json
    from pathlib import Path

    from ..plant.systems import get_system

    p = Path(path)
    try:
        d = json.loads(p.read_text())
    except OSError as exc:
        raise ConfigError(f"cannot read {p}: {exc.strerror or exc}") from None
    except (ValueError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{p} is not JSON ({exc})") from None
    if not isinstance(d, dict) or not isinstance(d.get("config"), dict) or not isinstance(d.get("results"), list):
        raise ConfigError(f"{p} is not a qsid sweep result (needs 'config' and 'results')")
    if "system_definition" not in d["config"]:
        raise ConfigError(
            f"{p} was written without the full configuration (no system_definition): "
            "re-run that sweep with this qsid to get a file that can be loaded"
        )
    fmt = d.get("result_format", 1)
    if not isinstance(fmt, int) or isinstance(fmt, bool) or fmt > RESULT_FORMAT:
        raise ConfigError(
            f"{p} has result_format {fmt!r}; this qsid reads formats 1 to {RESULT_FORMAT} (a newer qsid wrote it?)"
        )
    cfg = SweepConfig.from_dict(d["config"])
    rows = {int(r["bits"]): StoredRow(_upgrade_row(r, fmt)) for r in d["results"]}
    nan = float("nan")
    return SweepResult(
        cfg,
        get_system(cfg.system),
        tuple(sorted(rows)),
        {},
        {},
        {},
        None,
        float(d["slope_A"]) if d.get("slope_A") is not None else nan,
        float(d["slope_B"]) if d.get("slope_B") is not None else nan,
        d.get("timing_s") or {},
        rows=rows,
        version=str(d.get("qsid_version", "")),
        ranges=d.get("ranges"),
        true_cost=d.get("mpc_cost_true_model"),
        true_errors={k: d.get(f"{k}_true_model") for k in ("steady_state_error", "tracking_error")},
    )
