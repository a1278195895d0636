"""Sweeps over the word length for a nonlinear plant: quantized EDMD, its de-biased form, Koopman MPC.

For each realization (an independent dither draw shared by every word length, as the linear sweeps do)
and each word length ``b``: the lifted moments of the quantized training data
(:func:`~qsid_core.identification.quantized_lifted_moments`), the lifted model by the chosen estimator
(:func:`~qsid_core.identification.edmd`), its relative errors against the EDMD of the *same unquantized
data*, its multi-step prediction error on held-out runs of the true plant, and the Koopman MPC built on
it run on the true plant from the plant's ``x0`` (:func:`~qsid_core.control.run_koopman_loops`).

The linear certificates (Theorem 1's error model, the small-gain and ultimate-bound results) assume a
linear plant: they are not computed here and the result says so (:data:`NO_CERTIFICATES`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..control import CONVERGED_RADIUS, MPCConfig, run_koopman_loops
from ..errors import ConfigError, IdentificationError, check_choice, check_float, check_int
from ..identification import (
    ESTIMATORS,
    LARGE_DATA_HYPOTHESES,
    Lifting,
    edmd,
    exact_lifted_moments,
    large_data_limit,
    parse_lifting,
    prediction_error,
    quantized_lifted_realizations,
)
from ..plant import NonlinearDataset, NonlinearSystem, get_nonlinear, simulate_nonlinear
from ..quantization import MAX_BITS, QuantizerSpec
from .koopman_rows import ACC_KEYS, large_data_entry, no_exact_correction, predict, record, row

__all__ = [
    "KOOPMAN_MPC",
    "KOOPMAN_MPC_UNUSED",
    "NO_CERTIFICATES",
    "KoopmanConfig",
    "KoopmanResult",
    "run_koopman_sweep",
]

#: The MPC of the nonlinear sweeps by default: 1 s horizon, 10 s of closed loop (dt = 0.05).
KOOPMAN_MPC = MPCConfig(horizon=20, steps=200, verify_steps=None)
#: What the nonlinear results say about the linear certificates.
NO_CERTIFICATES = (
    "the linear certificates (Theorem 1's error model, small gain, ultimate bound, b_letter, b_robust) "
    "assume a linear plant and do not apply to a nonlinear one: only observed outcomes are reported"
)
#: Held-out runs for the prediction error: runs, steps, and the default prediction horizon H (the error is over
#: steps 1..H).
HELD_OUT = (50, 40, 20)
#: The :class:`MPCConfig` fields the Koopman loops do not use (exact state feedback, no disturbance, regulation
#: to 0 without state constraints; the verdict is by ``radius`` and the sane box): a value other than
#: ``MPCConfig()``'s is refused, never silently ignored. ``verify_steps`` is not used either and not checked
#: (:data:`KOOPMAN_MPC` leaves it None, a linear study's MPC table may hold any value).
KOOPMAN_MPC_UNUSED = (
    "x_max",
    "xf_max",
    "x_ref",
    "disturbance",
    "disturbance_kind",
    "feedback_bits",
    "feedback_noise",
    "loop_seed",
    "reference",
    "tracking",
)


@dataclass(frozen=True)
class KoopmanConfig:
    """A word-length sweep of a nonlinear plant.

    Parameters
    ----------
    system : str or NonlinearSystem
        A nonlinear preset (``van-der-pol``, ``duffing``, ``pendulum``) or a plant.
    lifting : str
        Dictionary spec (``poly:3``, ``rbf:K``, ``identity``; see :func:`~qsid_core.identification.parse_lifting`).
    estimator : {"ls", "bcls"}
    bits : tuple of int
        Word lengths (every state and input).
    trajectories, steps : int
        Training runs and samples per run (default 2000 x 100).
    realizations : int
        Dither realizations per b.
    data_seed, dither_seed : int
        Seeds of the training data (and held-out runs, and the RBF centres) and of the dither.
    quantizer : QuantizerSpec
        Dither, range, guard band (default: subtractive, per-channel, guard band on).
    mpc : MPCConfig or None
        The Koopman MPC (default :data:`KOOPMAN_MPC`); None skips the loops. Fields the loops do not use
        (:data:`KOOPMAN_MPC_UNUSED`) must keep ``MPCConfig()``'s values.
    radius : float, > 0
        Convergence radius of the loops' verdict (2-norm of the final state).
    prediction_horizon : int, 1..40
        Steps H of the prediction error: the relative RMS over k = 1..H of the prediction of each held-out run from
        its first sample (:data:`HELD_OUT`: 50 runs of 40 samples; :func:`~qsid_core.identification.prediction_error`).
    state_amplitude : float or None, > 0
        ``a`` of the training runs' x0 ~ U[-a, a]^n (None: the plant's ``amplitude``, 2 for the presets).
    input_amplitude : float, > 0
        ``A`` of the training inputs u ~ U[-A, A]^m.
    box : float or None, > 0
        The sane box ``|x_i| <= box`` (None: the plant's, 50 for the presets): a training run beyond it is
        reported and left out; a closed loop beyond it has diverged.
    """

    system: str | NonlinearSystem = "van-der-pol"
    lifting: str = "poly:3"
    estimator: str = "ls"
    bits: tuple[int, ...] = tuple(range(2, 9))
    trajectories: int = 2000
    steps: int = 100
    realizations: int = 20
    data_seed: int = 0
    dither_seed: int = 1
    quantizer: QuantizerSpec = field(default_factory=QuantizerSpec)
    mpc: MPCConfig | None = KOOPMAN_MPC
    radius: float = CONVERGED_RADIUS
    prediction_horizon: int = HELD_OUT[2]
    state_amplitude: float | None = None
    input_amplitude: float = 1.0
    box: float | None = None

    def __post_init__(self) -> None:
        check_choice("estimator", self.estimator, ESTIMATORS)
        if not self.bits:
            raise ConfigError("bits must name at least one word length")
        object.__setattr__(self, "bits", tuple(check_int("bits", b, 1, MAX_BITS) for b in self.bits))
        check_int("trajectories", self.trajectories, 1, 100_000)
        check_int("steps", self.steps, 1, 1_000_000)
        check_int("realizations", self.realizations, 1, 10_000)
        check_int("data seed", self.data_seed, 0)
        check_int("dither seed", self.dither_seed, 0)
        if not isinstance(self.quantizer, QuantizerSpec):
            raise ConfigError("quantizer must be a QuantizerSpec")
        object.__setattr__(self, "radius", check_float("radius", self.radius, 0.0, 1e12, lo_open=True))
        check_int("prediction horizon", self.prediction_horizon, 1, HELD_OUT[1])
        amp = check_float("input amplitude", self.input_amplitude, 0.0, 1e12, lo_open=True)
        object.__setattr__(self, "input_amplitude", amp)
        for name, label in (("state_amplitude", "state amplitude"), ("box", "box")):
            v = getattr(self, name)
            if v is not None:
                object.__setattr__(self, name, check_float(label, v, 0.0, 1e12, lo_open=True))
        if self.mpc is not None:
            if not isinstance(self.mpc, MPCConfig):
                raise ConfigError("mpc must be an MPCConfig or None")
            plain = MPCConfig()
            used = [k for k in KOOPMAN_MPC_UNUSED if getattr(self.mpc, k) != getattr(plain, k)]
            if used:
                raise ConfigError(
                    f"mpc.{used[0]}: the Koopman MPC does not use it (exact state feedback, no disturbance, "
                    "regulation to 0 without state constraints); leave it at its default"
                )

    def plant(self) -> NonlinearSystem:
        """The plant (a preset by name), with this config's ``state_amplitude`` and ``box`` where set."""
        s = get_nonlinear(self.system)
        if self.state_amplitude is None and self.box is None:
            return s
        a = s.amplitude if self.state_amplitude is None else self.state_amplitude
        return replace(s, amplitude=a, box=s.box if self.box is None else self.box)

    def dictionary(self) -> Lifting:
        """The lifting for the plant's state (RBF centres over the training amplitude, seeded by ``data_seed``)."""
        s = self.plant()
        return parse_lifting(self.lifting, s.n, s.amplitude, self.data_seed)


@dataclass
class KoopmanResult:
    """A finished nonlinear sweep: one row per word length, and what they are compared with.

    Attributes
    ----------
    config : KoopmanConfig
    rows : list of dict
        Per b (JSON-ready): ``bits``, ``eps_x``, ``eps_u``, ``err_G`` / ``err_A`` / ``err_B`` and
        ``prediction_error`` as ``{mean, std}``, ``overload_fraction``, ``bcls_fallbacks``,
        ``ident_failures``, ``stabilized_fraction``, ``closed_loop_outcomes``, ``within_radius`` (loops ending within ``radius``) and
        ``settled_offset`` ({median, max}) (None without loops),
        ``large_data`` (the estimator's large-data limit: ``err_G`` against the unquantized EDMD, None with a
        ``note`` where no exact formula exists), ``notes``.
    reference_prediction_error : float
        The unquantized EDMD's prediction error (the floor the quantized models approach).
    reference_outcome : str or None
        The unquantized EDMD's Koopman MPC verdict.
    reference_offset : float or None
        Its loop's settled offset: what the dictionary alone leaves (NaN: the loop diverged or failed).
    data_report : str
        Runs left out of the training data ("" when none).
    timing_s : float
    """

    config: KoopmanConfig
    rows: list[dict[str, Any]]
    reference_prediction_error: float
    reference_outcome: str | None
    data_report: str
    features: int
    runs_used: int
    timing_s: float = 0.0
    reference_offset: float | None = None

    def _mpc(self, s: NonlinearSystem) -> dict[str, Any]:
        """The loops' settings as run (the plant's defaults where the config leaves them unset)."""
        m = self.config.mpc
        assert m is not None
        return {
            "horizon": m.horizon,
            "steps": m.steps,
            "u_max": list(m.u_max) if isinstance(m.u_max, tuple) else [m.u_max],
            "x0": list(m.x0 or s.x0),
            "Q": list(m.Q or s.Q),
            "R": list(m.R or s.R),
            "terminal_weight": "C'QC" if self.config.lifting != "identity" else "DARE",
        }

    def to_dict(self) -> dict[str, Any]:
        """Strict-JSON-ready summary."""
        c = self.config
        s = c.plant()
        q = c.quantizer
        return {
            "kind": "koopman",
            "system": s.name,
            "config": {
                "lifting": c.lifting,
                "features": self.features,
                "estimator": c.estimator,
                "bits": list(c.bits),
                "trajectories": c.trajectories,
                "steps": c.steps,
                "realizations": c.realizations,
                "data_seed": c.data_seed,
                "dither_seed": c.dither_seed,
                "state_amplitude": s.amplitude,
                "input_amplitude": c.input_amplitude,
                "box": s.box,
                "dither": q.dither,
                "range": q.range_mode,
                "guard": q.guard,
                "mpc": None if c.mpc is None else self._mpc(s),
                "convergence_radius": c.radius,
                "held_out": {"runs": HELD_OUT[0], "steps": HELD_OUT[1], "horizon": c.prediction_horizon},
            },
            "data": {"runs_used": self.runs_used, "left_box": self.data_report},
            "certificates": NO_CERTIFICATES,
            "large_data_hypotheses": list(LARGE_DATA_HYPOTHESES),
            "reference": {
                "prediction_error": self.reference_prediction_error,
                "closed_loop_outcome": self.reference_outcome,
                "settled_offset": self.reference_offset,
            },
            "results": self.rows,
            "timing_s": {"total": self.timing_s},
        }


def held_out_runs(system: NonlinearSystem, cfg: KoopmanConfig) -> NonlinearDataset:
    """The held-out runs of the prediction error (:data:`HELD_OUT`), seeded apart from the training runs."""
    return simulate_nonlinear(system, HELD_OUT[0], HELD_OUT[1], cfg.data_seed + 104729, cfg.input_amplitude)


def run_koopman_sweep(cfg: KoopmanConfig) -> KoopmanResult:
    """Run the sweep (see the module docstring).

    Raises
    ------
    ConfigError, SystemDefinitionError, IdentificationError
        Bad settings, a vector field that fails, or no model from the unquantized data.
    """
    t0 = time.perf_counter()
    system = cfg.plant()
    lifting = cfg.dictionary()
    amp = cfg.input_amplitude
    data: NonlinearDataset = simulate_nonlinear(system, cfg.trajectories, cfg.steps, cfg.data_seed, amp)
    held = held_out_runs(system, cfg)
    horizon = cfg.prediction_horizon
    if data.T < lifting.L + system.m:
        raise IdentificationError(
            f"samples: {data.T} samples cannot fit {lifting.L + system.m} unknowns per row "
            f"({lifting.L} features + {system.m} inputs); use more runs or steps, or a smaller dictionary"
        )
    ref = edmd(exact_lifted_moments(data, lifting), lifting.C, "ls")
    ref_loop = None if cfg.mpc is None else run_koopman_loops([ref], lifting, system, cfg.mpc, cfg.radius)
    nb = len(cfg.bits)
    per: list[dict[str, list[Any]]] = [{k: [] for k in ACC_KEYS} for _ in range(nb)]
    unbiased = cfg.estimator == "bcls"
    seeds = np.random.SeedSequence(cfg.dither_seed).spawn(cfg.realizations)
    for moms in quantized_lifted_realizations(data, lifting, cfg.bits, cfg.quantizer, seeds, unbiased):
        for acc, mom in zip(per, moms, strict=True):
            record(acc, mom, cfg.estimator, lifting, ref)
        predict(per, lifting, held, horizon)
    rows = [row(b, acc, lifting, system, cfg.mpc, cfg.radius) for b, acc in zip(cfg.bits, per, strict=True)]
    correction = no_exact_correction(lifting, cfg.quantizer)
    # BCLS's limit is the unquantized EDMD itself wherever the correction is exact: LS's limits only
    limits = large_data_limit(data, lifting, cfg.bits, cfg.quantizer) if cfg.estimator == "ls" else [None] * nb
    for r, limit in zip(rows, limits, strict=True):
        r["large_data"] = large_data_entry(limit, cfg.estimator, ref, correction)
    return KoopmanResult(
        cfg,
        rows,
        prediction_error(ref, lifting, held, horizon),
        None if ref_loop is None else ref_loop.outcome[0],
        data.report,
        lifting.L,
        data.trajectories,
        time.perf_counter() - t0,
        None if ref_loop is None else float(ref_loop.settled_offset[0]),
    )
