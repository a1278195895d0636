"""Linear MPC on an identified model (run in closed loop by :mod:`qsid_core.control.closed_loop`).

The letter's problem (eq. (2)) with horizon ``Th``::

    min  sum_{k<Th} (x_k - r)'Q(x_k - r) + u_k'R u_k + (x_Th - r)'Qf(x_Th - r)
    s.t. x_{k+1} = A^ x_k + B^ u_k,  x_0 = measured state,
         |u_k| <= u_max,  |x_k| <= x_max (k = 1..Th, optional),  |x_Th| <= xf_max (optional)

``Qf`` defaults to the DARE solution of ``(A^, B^, Q, R)``. The state box is
never put on ``x_0`` (the measured state): with model mismatch that could make
the problem infeasible.

The settings are :class:`MPCConfig`; the controller that solves the problem for one model is
:class:`~qsid_core.control.controller.MPCController`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ConfigError, FailureKind, check_choice, check_float, check_int
from ..plant.lti import LTISystem
from ..validate import as_float_array
from .mpc_weights import MPCWeights
from .reference import reference_samples

__all__ = ["MPCConfig", "FAILURE_KINDS", "SOLVERS", "TRACKING"]

#: every failure kind's value, in :class:`FailureKind` order
FAILURE_KINDS = tuple(k.value for k in FailureKind)
#: QP solvers for the steps where a bound is active
SOLVERS = ("daqp", "osqp")
#: cost forms of reference tracking: the letter's, or offset-free with a steady-state input target
TRACKING = ("letter", "offset-free")


def _vec(name: str, v: ArrayLike | None, k: int | None, positive: bool = False) -> tuple[float, ...] | None:
    if v is None:
        return None
    arr = np.atleast_1d(as_float_array(name, v, ndim_max=1)).reshape(-1)  # finite, <= MAX_MAGNITUDE, not empty
    if positive and np.any(arr <= 0):
        raise ConfigError(f"{name} must be positive; got {v!r}")
    if k is not None and arr.size not in (1, k):
        raise ConfigError(f"{name} must have 1 or {k} entries; got {arr.size}")
    return tuple(arr.tolist())


@dataclass(frozen=True, init=False)
class MPCConfig:
    """MPC settings (unset weights and x0 come from the system's defaults).

    Parameters
    ----------
    horizon : int, 1..200
        Prediction horizon ``Th`` (default 10, the letter's).
    steps : int, 1..10000
        Closed-loop steps on the true system (``mpc_steps``, default 50).
    u_max : float or tuple, > 0
        Input box ``|u_i| <= u_max_i`` (default 1).
    x_max : float or tuple, optional
        State box on ``x_1 .. x_Th`` (never on the measured ``x_0``).
    xf_max : float or tuple, optional
        Terminal box on ``x_Th``.
    Q, R : tuple of floats, optional
        Diagonals of the weights (default: the system's Q and R).
    Qf : tuple of floats, optional
        Diagonal of the terminal weight (default: DARE solution for the model).
    x0 : tuple of floats, optional
        Initial state (default: the system's x0).
    x_ref : tuple of floats, optional
        Constant reference (default 0).
    eps : float
        OSQP absolute and relative tolerance (default 1e-9; only for
        ``solver="osqp"``; the result is clipped to the input box as well).
    max_iter : int
        Iteration limit of the QP solver.
    solver : {"daqp", "osqp"}
        QP solver for the steps where a bound is active: DAQP on the condensed
        problem (default, exact active set) or OSQP on the sparse one (the
        previous engine, kept as a reference).
    disturbance : float >= 0
        Standard deviation of the process disturbance added to the true plant in
        the closed loop (:mod:`qsid_core.control.loop_noise`; default 0).
    disturbance_kind : {"gaussian", "uniform"}
    feedback_bits : int or None, 1..32
        The MPC measures the state through a quantizer of this many bits per state
        (subtractive dither, the training data's range); None: exact (default).
    feedback_noise : float >= 0
        Standard deviation of sensor noise on that measurement (default 0).
    loop_seed : int >= 0
        Seed of the disturbance, feedback dither and sensor noise (shared by every loop).
    tracking : {"letter", "offset-free"}
        The letter's cost ``(x - r)'Q(x - r) + u'R u`` (default) or the offset-free form
        ``(x - r)'Q(x - r) + (u - u_ref)'R(u - u_ref)`` with ``u_ref = B^+ (I - A^) r`` per
        model (the input that holds the model at ``r``, least squares when ``r`` is not an
        equilibrium); applies to ``x_ref`` and to ``reference``.
    reference : str or tuple of rows, optional
        A time-varying reference with preview (:mod:`qsid_core.control.reference`):
        ``"step:STATE:AMP:TIME"``, ``"sine:STATE:AMP:PERIOD"``, ``"square:STATE:AMP:PERIOD"``
        or samples (one row per step, one column per state). Excludes ``x_ref``.
    verify_steps : int or None, 0..1000000
        At most this many closed-loop steps beyond ``steps`` to decide whether a
        loop converges, stays bounded or diverges (:mod:`qsid_core.control.verdicts`;
        default 20000); None skips the verdicts.
    """

    horizon: int = 10
    steps: int = 50
    u_max: tuple[float, ...] = (1.0,)
    x_max: tuple[float, ...] | None = None
    xf_max: tuple[float, ...] | None = None
    Q: tuple[float, ...] | None = None
    R: tuple[float, ...] | None = None
    Qf: tuple[float, ...] | None = None
    x0: tuple[float, ...] | None = None
    x_ref: tuple[float, ...] | None = None
    eps: float = 1e-9
    max_iter: int = 20000
    solver: str = "daqp"
    verify_steps: int | None = 20000
    disturbance: float = 0.0
    disturbance_kind: str = "gaussian"
    feedback_bits: int | None = None
    feedback_noise: float = 0.0
    loop_seed: int = 0
    reference: str | tuple[tuple[float, ...], ...] | None = None
    tracking: str = "letter"

    def __init__(
        self,
        horizon: int = 10,
        steps: int = 50,
        u_max: float | Sequence[float] = 1.0,
        x_max: float | Sequence[float] | None = None,
        xf_max: float | Sequence[float] | None = None,
        Q: float | Sequence[float] | None = None,
        R: float | Sequence[float] | None = None,
        Qf: float | Sequence[float] | None = None,
        x0: float | Sequence[float] | None = None,
        x_ref: float | Sequence[float] | None = None,
        eps: float = 1e-9,
        max_iter: int = 20000,
        solver: str = "daqp",
        verify_steps: int | None = 20000,
        disturbance: float = 0.0,
        disturbance_kind: str = "gaussian",
        feedback_bits: int | None = None,
        feedback_noise: float = 0.0,
        loop_seed: int = 0,
        reference: str | Sequence[Sequence[float]] | None = None,
        tracking: str = "letter",
    ) -> None:
        # the arguments as given; __post_init__ checks them and stores what the fields hold (tuples of floats)
        given: dict[str, object] = dict(
            horizon=horizon, steps=steps, u_max=u_max, x_max=x_max, xf_max=xf_max, Q=Q, R=R, Qf=Qf, x0=x0
        )
        given.update(x_ref=x_ref, eps=eps, max_iter=max_iter, solver=solver, verify_steps=verify_steps)
        given.update(disturbance=disturbance, disturbance_kind=disturbance_kind, feedback_bits=feedback_bits)
        given.update(feedback_noise=feedback_noise, loop_seed=loop_seed, reference=reference, tracking=tracking)
        for name, value in given.items():
            object.__setattr__(self, name, value)
        self.__post_init__()

    def nominal(self) -> MPCConfig:
        """The same MPC law regulating to the constant ``x_ref`` in the letter's form, with exact state
        feedback and no disturbance (both forms share the law's linear part, hence its stability)."""
        return replace(self, disturbance=0.0, feedback_bits=None, feedback_noise=0.0, reference=None, tracking="letter")

    @property
    def noisy(self) -> bool:
        """Whether the loop is disturbed or measures the state inexactly."""
        return bool(self.disturbance or self.feedback_noise or self.feedback_bits is not None)

    def __post_init__(self) -> None:
        check_choice("solver", self.solver, SOLVERS)
        check_choice("disturbance kind", self.disturbance_kind, ("gaussian", "uniform"))
        object.__setattr__(self, "disturbance", check_float("disturbance", self.disturbance, 0.0, 1e6))
        object.__setattr__(self, "feedback_noise", check_float("feedback noise", self.feedback_noise, 0.0, 1e6))
        if self.feedback_bits is not None:
            check_int("feedback bits", self.feedback_bits, 1, 32)
        check_int("loop seed", self.loop_seed, 0)
        check_choice("tracking", self.tracking, TRACKING)
        if self.tracking == "offset-free" and self.solver == "osqp":
            raise ConfigError("the offset-free form needs solver='daqp' (the condensed problem)")
        if self.reference is not None and not isinstance(self.reference, str):
            rows = np.atleast_2d(np.asarray(self.reference, dtype=float))
            if rows.ndim != 2 or rows.size == 0 or not np.all(np.isfinite(rows)):
                raise ConfigError("reference samples must be a non-empty table of finite numbers (rows: steps)")
            object.__setattr__(self, "reference", tuple(tuple(r) for r in rows.tolist()))
        if self.reference is not None and self.solver == "osqp":
            raise ConfigError("a time-varying reference needs solver='daqp' (the condensed problem)")
        if self.reference is not None and self.x_ref is not None:
            raise ConfigError("give either a constant x_ref or a time-varying reference, not both")
        if self.verify_steps is not None:
            check_int("verify steps", self.verify_steps, 0, 1_000_000)
        check_int("horizon", self.horizon, 1, 200)
        check_int("mpc steps", self.steps, 1, 10000)
        check_float("OSQP eps", self.eps, 0.0, 1e-2, lo_open=True)
        check_int("max_iter", self.max_iter, 1)
        if self.u_max is None:  # the controller always has an input box (the letter's |u| <= 1 by default)
            raise ConfigError(
                "u_max must be a positive number or one per input (the input box |u_i| <= u_max_i); got None"
            )
        object.__setattr__(self, "u_max", _vec("u_max", self.u_max, None, positive=True))
        object.__setattr__(self, "x_max", _vec("x_max", self.x_max, None, positive=True))
        object.__setattr__(self, "xf_max", _vec("xf_max", self.xf_max, None, positive=True))
        for nm in ("Q", "R", "Qf", "x0", "x_ref"):
            object.__setattr__(self, nm, _vec(nm, getattr(self, nm), None))
        for nm in ("Q", "Qf"):
            v = getattr(self, nm)
            if v is not None and min(v) < 0:
                raise ConfigError(f"{nm} diagonal must be >= 0; got {v}")
        if self.R is not None and min(self.R) <= 0:
            raise ConfigError(f"R diagonal must be > 0; got {self.R}")

    def resolve(self, system: LTISystem) -> MPCWeights:
        """Weights, bounds and x0 as arrays for ``system`` (shapes checked).

        Raises
        ------
        ConfigError
            If a vector has neither 1 nor the system's number of entries.
        """
        n, m = system.n, system.m

        def full(name: str, v: tuple[float, ...], k: int) -> NDArray[np.float64]:
            arr = np.asarray(v, dtype=float)
            if arr.size == 1:
                arr = np.repeat(arr, k)
            if arr.size != k:
                raise ConfigError(f"{name} must have 1 or {k} entries for system {system.name!r}; got {arr.size}")
            return arr

        Q = np.diag(full("Q", self.Q, n)) if self.Q is not None else np.array(system.Q, dtype=float)
        R = np.diag(full("R", self.R, m)) if self.R is not None else np.array(system.R, dtype=float)
        x_ref = full("x_ref", self.x_ref, n) if self.x_ref is not None else np.zeros(n)
        return MPCWeights(
            Q=Q,
            R=R,
            Qf=None if self.Qf is None else np.diag(full("Qf", self.Qf, n)),
            x0=full("x0", self.x0, n) if self.x0 is not None else np.array(system.x0, dtype=float),
            x_ref=x_ref if self.tracking == "letter" else np.zeros(n),
            u_max=full("u_max", self.u_max, m),
            x_max=None if self.x_max is None else full("x_max", self.x_max, n),
            xf_max=None if self.xf_max is None else full("xf_max", self.xf_max, n),
            reference=self._reference_samples(system, x_ref),
        )

    def _reference_samples(self, system: LTISystem, x_ref: NDArray[np.float64]) -> NDArray[np.float64] | None:
        """The time-varying reference (a constant x_ref too in the offset-free form), or None."""
        length = self.steps + self.horizon + 1
        if self.reference is not None:
            return reference_samples(self.reference, system.state_names, length)
        if self.tracking == "offset-free":
            return np.tile(x_ref, (length, 1))
        return None
