"""python-control interop: ``control.StateSpace`` in, identified models out.

The engine identifies *full-state* systems ``x+ = A x + B u``: the data it
quantizes are the states themselves. A ``control.StateSpace`` carries outputs
``y = C x + D u`` as well, so the rule is explicit:

* ``outputs="full-state"`` (default): the system must measure its whole state,
  ``C = I_n`` and ``D = 0`` (to 1e-12); anything else is a
  :class:`~qsid_core.errors.SystemDefinitionError` that says so.
* ``outputs="ignore"``: take ``A`` and ``B`` and drop ``C`` and ``D`` (say so in
  your study: qsid then still quantizes and identifies the states, not ``y``).

Timebases: a discrete system keeps its ``dt`` (python-control's ``dt=True``,
"discrete, unspecified", becomes 1 sample unless ``dt`` is given); a continuous
one needs ``dt`` and is discretised with ``control.c2d`` (zero-order hold by
default); ``dt=None`` (either) is refused. Identified models come back as
``control.StateSpace(A^, B^, I, 0, dt)`` with the true system's ``dt`` and names.

python-control is imported inside the functions (importing it costs ~1.5 s).
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import SystemDefinitionError, check_choice
from .lti import LTISystem

__all__ = [
    "OUTPUT_RULES",
    "system_from_statespace",
    "system_to_statespace",
    "model_to_statespace",
    "identified_statespaces",
]

#: A ``control.StateSpace`` (python-control ships no type information).
StateSpace = Any


class _Identified(Protocol):
    """What :func:`identified_statespaces` reads of a :class:`~qsid_core.studies.stage_results.BitsIdentification`."""

    bits: int
    A_hat: NDArray[np.float64]
    B_hat: NDArray[np.float64]
    failed: NDArray[np.bool_]


OUTPUT_RULES = ("full-state", "ignore")
_TOL = 1e-12


def _labels(labels: Iterable[object], prefix: str) -> tuple[str, ...]:
    """python-control's labels, or () when they are its defaults ('x[0]', ...) so qsid's defaults apply."""
    texts = tuple(str(v) for v in labels)
    if all(re.fullmatch(rf"{prefix}\[\d+\]", v) for v in texts):
        return ()
    return texts


def _discrete(sys: StateSpace, dt: float | None, method: str) -> tuple[StateSpace, float]:
    """(discrete StateSpace, sample time) from a discrete or continuous StateSpace."""
    import control

    if sys.dt is None:
        raise SystemDefinitionError(
            "the StateSpace has an unspecified timebase (dt=None); build it with dt=0 "
            "(continuous, then give dt= to discretise) or dt>0 (discrete)"
        )
    if sys.dt is True:  # discrete, sample time not given
        return sys, 1.0 if dt is None else _positive_dt(dt)
    if sys.dt == 0:
        if dt is None:
            raise SystemDefinitionError(
                "the StateSpace is continuous-time (dt=0): give the sample time dt= to discretise it with control.c2d"
            )
        dt = _positive_dt(dt)
        return control.c2d(sys, dt, method=method), dt
    if dt is not None and not np.isclose(float(dt), float(sys.dt), rtol=1e-12, atol=0.0):
        raise SystemDefinitionError(
            f"the StateSpace is discrete with dt={sys.dt:g}; dt={dt!r} disagrees "
            "(leave dt out, or resample with control.sample_system first)"
        )
    return sys, float(sys.dt)


def _positive_dt(dt: Any) -> float:  # anything float() may take; the rest is refused in words
    try:
        v = float(dt)
    except (TypeError, ValueError):
        raise SystemDefinitionError(f"dt must be a positive number of seconds; got {dt!r}") from None
    if not (np.isfinite(v) and v > 0):
        raise SystemDefinitionError(f"dt must be a positive number of seconds; got {dt!r}")
    return v


def system_from_statespace(
    sys: StateSpace,
    dt: float | None = None,
    *,
    outputs: str = "full-state",
    method: str = "zoh",
    name: str | None = None,
    x0: ArrayLike | None = None,
    Q: ArrayLike | None = None,
    R: ArrayLike | None = None,
    description: str = "",
) -> LTISystem:
    """An :class:`LTISystem` from a ``control.StateSpace``.

    Parameters
    ----------
    sys : control.StateSpace
        Discrete (``dt > 0`` or ``dt=True``) or continuous (``dt = 0``), n states, m inputs.
    dt : float, optional
        Sample time in seconds: required for a continuous system (discretised by
        ``control.c2d(sys, dt, method)``); for a discrete one it must equal ``sys.dt``.
    outputs : {"full-state", "ignore"}
        How ``C`` and ``D`` are treated (see the module notes): require ``C = I``,
        ``D = 0``, or drop them.
    method : str
        ``c2d`` method for continuous systems (default ``"zoh"``, what sampled data see).
    name, x0, Q, R, description
        As in :class:`LTISystem` (defaults: ``sys.name`` unless python-control's
        automatic ``sys[k]``; first unit vector; identities).

    Returns
    -------
    LTISystem
        With ``A`` (n, n), ``B`` (n, m), ``dt`` and the state/input labels of ``sys``.

    Raises
    ------
    SystemDefinitionError
        Not a StateSpace, unclear timebase, missing/contradicting dt, or outputs
        that are not the full state under ``outputs="full-state"``.
    """
    import control

    check_choice("outputs", outputs, OUTPUT_RULES)
    if not isinstance(sys, control.StateSpace):
        raise SystemDefinitionError(
            f"expected a control.StateSpace; got {type(sys).__name__} "
            "(convert a transfer function with control.ss(...) first)"
        )
    dsys, dt = _discrete(sys, dt, method)
    A, B, C, D = (np.asarray(M, dtype=float) for M in (dsys.A, dsys.B, dsys.C, dsys.D))
    n = A.shape[0]
    if n == 0 or B.shape[1] == 0:
        raise SystemDefinitionError(f"the StateSpace needs at least one state and one input; got {n} and {B.shape[1]}")
    if outputs == "full-state":
        full = (
            C.shape == (n, n)
            and np.allclose(C, np.eye(n), rtol=0, atol=_TOL)
            and np.allclose(D, 0.0, rtol=0, atol=_TOL)
        )
        if not full:
            raise SystemDefinitionError(
                f"qsid identifies full-state systems: C must be the {n} x {n} identity and D zero; got C of shape "
                f"{C.shape}{'' if C.shape != (n, n) else ' (not I)'} -- pass outputs='ignore' to use A and B only"
            )
    auto = re.fullmatch(r"sys\[\d+\]", str(sys.name or ""))
    return LTISystem(
        name or ("statespace" if auto or not sys.name else str(sys.name)),
        A,
        B,
        x0=x0,
        Q=Q,
        R=R,
        dt=dt,
        description=description or f"from control.StateSpace ({'c2d ' + method if sys.dt == 0 else 'discrete'})",
        state_names=_labels(sys.state_labels, "x"),
        input_names=_labels(sys.input_labels, "u"),
    )


def model_to_statespace(
    A: ArrayLike,
    B: ArrayLike,
    dt: float,
    *,
    name: str = "model",
    states: Iterable[str] | None = None,
    inputs: Iterable[str] | None = None,
) -> StateSpace:
    """``control.StateSpace(A, B, I, 0, dt)``: a full-state model as python-control sees it.

    Parameters
    ----------
    A : array_like, shape (n, n)
    B : array_like, shape (n, m)
    dt : float
        Sample time in seconds (> 0: the model is discrete).
    name, states, inputs
        Names (``states``/``inputs`` also name the outputs ``y = x``).
    """
    import control

    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    n, m = B.shape
    if A.shape != (n, n):
        raise SystemDefinitionError(f"A must be {n} x {n} to go with B of shape {B.shape}; got {A.shape}")
    kw: dict[str, list[str]] = {}
    if states is not None:
        kw.update(states=list(states), outputs=list(states))
    if inputs is not None:
        kw["inputs"] = list(inputs)
    return control.ss(A, B, np.eye(n), np.zeros((n, m)), _positive_dt(dt), name=name, **kw)


def system_to_statespace(system: LTISystem) -> StateSpace:
    """The true plant of an :class:`LTISystem` as ``control.StateSpace`` (``C = I``, ``D = 0``, its ``dt``)."""
    return model_to_statespace(
        system.A, system.B, system.dt, name=system.name, states=system.state_names, inputs=system.input_names
    )


def identified_statespaces(ident: _Identified, system: LTISystem) -> list[StateSpace | None]:
    """Every realization's identified model at one word length as ``control.StateSpace``.

    Parameters
    ----------
    ident : BitsIdentification
        From :meth:`Experiment.identification` or ``SweepResult.identification[b]``.
    system : LTISystem
        The true system (gives ``dt`` and the names).

    Returns
    -------
    list, length R
        ``control.StateSpace`` per realization, ``None`` where identification failed.
    """
    out: list[StateSpace | None] = []
    for r, (A, B) in enumerate(zip(ident.A_hat, ident.B_hat)):
        if ident.failed[r] or not (np.all(np.isfinite(A)) and np.all(np.isfinite(B))):
            out.append(None)
            continue
        out.append(
            model_to_statespace(
                A,
                B,
                system.dt,
                name=f"{system.name} b={ident.bits} r={r}",
                states=system.state_names,
                inputs=system.input_names,
            )
        )
    return out
