"""The true plant: :class:`LTISystem`, a discrete-time ``x+ = A x + B u`` with its regulation task.

Validated on construction (shapes, finite entries, ``Q`` positive semidefinite,
``R`` positive definite); an uncontrollable ``(A, B)`` warns with
:class:`UncontrollableWarning`. Presets and system files: :mod:`qsid_core.plant.systems`.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ConfigError, SystemDefinitionError, check_float, short_repr
from ..validate import MAX_MAGNITUDE, as_float_array, as_matrix, check_text, weight_matrix

__all__ = ["LTISystem", "UncontrollableWarning", "MAX_STATES", "MAX_INPUTS", "CTRB_RTOL", "balanced_pair"]


class UncontrollableWarning(UserWarning):
    """(A, B) is not controllable: identification works, MPC may not regulate."""


#: Largest number of states / inputs of a system (the controllability test builds an n x n*m matrix).
MAX_STATES = 100
MAX_INPUTS = 100
#: A singular value of the balanced controllability matrix counts when above this times the largest one.
CTRB_RTOL = 1e-9


def balanced_pair(A: np.ndarray, B: np.ndarray, sweeps: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """``(D^-1 A D / a, D^-1 B E / a)``: the pair in balanced units, for scale-invariant rank tests.

    ``D`` (states) and ``E`` (inputs) are diagonal powers of two (exact in floating point): each sweep
    makes every state's row norm in ``[A, B]`` equal its column norm in ``A`` (Osborne's balancing
    extended to the pair), then every input column the size of ``A``; ``a`` scales ``A`` to norm at most
    1 so that ``A^k`` cannot overflow. A change of state or input units is a diagonal ``D`` or ``E``, so
    ranks of the result do not depend on units; a similarity and a change of input basis leave the rank
    of the controllability matrix unchanged.

    Parameters
    ----------
    A : ndarray, shape (n, n); B : ndarray, shape (n, m)

    Returns
    -------
    (A_bal, B_bal) : ndarrays, shapes (n, n) and (n, m)
    """
    A = np.array(A, dtype=float)
    B = np.array(B, dtype=float)
    off = ~np.eye(A.shape[0], dtype=bool)
    for _ in range(sweeps):
        rows = np.sqrt((np.where(off, A, 0.0) ** 2).sum(axis=1) + (B**2).sum(axis=1))
        cols = np.sqrt((np.where(off, A, 0.0) ** 2).sum(axis=0))
        ok = (rows > 0) & (cols > 0)
        d = np.ones(A.shape[0])
        d[ok] = np.exp2(np.round(0.5 * np.log2(rows[ok] / cols[ok])))
        A = A * d[None, :] / d[:, None]
        B = B / d[:, None]
        size = max(float(np.abs(A).max()), np.finfo(float).tiny)
        bc = np.abs(B).max(axis=0)
        e = np.where(bc > 0, np.exp2(np.round(np.log2(size / np.where(bc > 0, bc, 1.0)))), 1.0)
        B = B * e[None, :]
        if np.all(d == 1.0) and np.all(e == 1.0):
            break
    a = float(np.abs(A).max())
    if a > 1.0:
        A, B = A / a, B / a
    return A, B


@dataclass(frozen=True, eq=False, init=False)
class LTISystem:
    """A true discrete-time LTI plant and its default regulation task.

    Parameters
    ----------
    name : str
        Short identifier (``"dc-motor"``, ``"boeing747"`` or a file stem).
    A : ndarray, shape (n, n)
        State matrix of ``x+ = A x + B u``.
    B : ndarray, shape (n, m)
        Input matrix.
    x0 : ndarray, shape (n,)
        Initial state of the MPC regulation task (default: first unit vector).
    Q : ndarray, shape (n, n)
        State weight, symmetric positive semidefinite (default: identity).
    R : ndarray, shape (m, m)
        Input weight, symmetric positive definite (default: identity).
    dt : float
        Sample time in seconds (informative).
    description : str
        One line for listings.

    Raises
    ------
    SystemDefinitionError
        If shapes disagree or entries are not finite, or Q/R are not PSD/PD.

    Warns
    -----
    UncontrollableWarning
        If ``rank ctrb(A, B) < n``.
    """

    name: str
    A: NDArray[np.float64]
    B: NDArray[np.float64]
    x0: NDArray[np.float64]
    Q: NDArray[np.float64]
    R: NDArray[np.float64]
    dt: float = 1.0
    description: str = ""
    state_names: tuple[str, ...] = field(default=())
    input_names: tuple[str, ...] = field(default=())

    def __init__(
        self,
        name: str,
        A: ArrayLike,
        B: ArrayLike,
        x0: ArrayLike | None = None,
        Q: ArrayLike | None = None,
        R: ArrayLike | None = None,
        dt: float = 1.0,
        description: str = "",
        state_names: Sequence[str] = (),
        input_names: Sequence[str] = (),
    ) -> None:
        check_text("system name", name, SystemDefinitionError)
        check_text("description", description, SystemDefinitionError)
        try:
            dt = check_float("dt", dt, 0.0, lo_open=True)
        except ConfigError:
            raise SystemDefinitionError(
                f"dt (the sample time) must be a positive, finite number of seconds; got {short_repr(dt)}"
            ) from None
        Am, Bm = _plant_matrices(A, B)
        x0v, Qm, Rm = _task(x0, Q, R, Am.shape[0], Bm.shape[1])
        names, inames = _names(state_names, input_names, Am.shape[0], Bm.shape[1])
        for arr in (Am, Bm, x0v, Qm, Rm):
            arr.setflags(write=False)
        values = dict(name=name, A=Am, B=Bm, x0=x0v, Q=Qm, R=Rm, dt=dt, description=description)
        for key, value in values.items():
            object.__setattr__(self, key, value)
        object.__setattr__(self, "state_names", names)
        object.__setattr__(self, "input_names", inames)
        if not self.controllable:
            warnings.warn(
                f"system {self.name!r}: (A, B) is not controllable (rank of the controllability "
                f"matrix {self.controllability_rank} < n = {self.n}); MPC may fail to regulate",
                UncontrollableWarning,
                stacklevel=2,
            )

    @property
    def n(self) -> int:
        """Number of states."""
        return int(self.A.shape[0])

    @property
    def m(self) -> int:
        """Number of inputs."""
        return int(self.B.shape[1])

    @property
    def eigenvalues(self) -> np.ndarray:
        """Eigenvalues of the true A, shape (n,) complex."""
        return np.linalg.eigvals(self.A)

    @property
    def G(self) -> np.ndarray:
        """``[A, B]``, shape (n, n+m)."""
        return np.hstack([self.A, self.B])

    @property
    def controllability_rank(self) -> int:
        """Rank of the controllability matrix ``[B, AB, ..., A^(n-1) B]`` of the balanced pair (:func:`balanced_pair`).

        Scale-invariant: a change of the units of a state or of an input leaves it unchanged (the pair is
        balanced first, then the rank uses a tolerance relative to the largest singular value,
        :data:`CTRB_RTOL`). Equals python-control's ``ctrb`` rank (numpy's default tolerance) on the
        presets and on the plants of the docs' "bring your own plant" page. Built with numpy, so
        building a system never imports python-control (~2-5 s).
        """
        A, B = balanced_pair(self.A, self.B)
        blocks = [B]
        for _ in range(self.n - 1):
            blocks.append(A @ blocks[-1])
        C = np.hstack(blocks)
        try:
            s = np.linalg.svd(C, compute_uv=False)
        except np.linalg.LinAlgError:  # the SVD did not converge: badly scaled (A, B)
            raise SystemDefinitionError(
                "cannot decide whether (A, B) is controllable: the controllability matrix is too badly scaled"
            ) from None
        return int(np.sum(s > CTRB_RTOL * s[0])) if s.size and s[0] > 0 else 0

    @property
    def controllable(self) -> bool:
        """True if ``rank ctrb(A, B) == n`` (Assumption 1 of the letter)."""
        return self.controllability_rank == self.n

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready description (what :func:`system_from_dict` reads back)."""
        return {
            "name": self.name,
            "A": self.A.tolist(),
            "B": self.B.tolist(),
            "x0": self.x0.tolist(),
            "Q": self.Q.tolist(),
            "R": self.R.tolist(),
            "dt": self.dt,
        }


def _plant_matrices(A: ArrayLike, B: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(A, B)`` checked: A square (n, n), B (n, m), sizes within the limits, not both (nearly) zero."""
    Am = as_matrix("A", A, (None, None))
    n = Am.shape[0]
    if Am.shape != (n, n):
        raise SystemDefinitionError(f"A must be square; got shape {Am.shape}")
    if n > MAX_STATES:
        raise SystemDefinitionError(f"A: at most {MAX_STATES} states; got {n}")
    Bm = as_matrix("B", B, (n, None))
    m = Bm.shape[1]
    if m > MAX_INPUTS:
        raise SystemDefinitionError(f"B: at most {MAX_INPUTS} inputs; got {m}")
    if max(np.abs(Am).max(), np.abs(Bm).max()) < 1.0 / MAX_MAGNITUDE:
        raise SystemDefinitionError(
            f"A and B are both (nearly) all zeros (every entry below {1.0 / MAX_MAGNITUDE:g} in magnitude): "
            "there is nothing to identify and relative model errors are undefined"
        )
    return Am, Bm


def _task(
    x0: ArrayLike | None, Q: ArrayLike | None, R: ArrayLike | None, n: int, m: int
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """The regulation task ``(x0, Q, R)`` checked, shapes (n,), (n, n), (m, m); defaults: the first unit
    vector, identities."""
    if x0 is None:
        x0v = np.eye(n)[0]
    else:
        x0v = as_float_array("x0", x0, ndim_max=2, error=SystemDefinitionError, what=f"a list of {n} numbers")
        x0v = x0v.reshape(-1)
    if x0v.shape != (n,):
        raise SystemDefinitionError(f"x0 must be {n} finite numbers; got {short_repr(x0)}")
    Qm = np.eye(n) if Q is None else weight_matrix("Q", Q, n)
    Rm = np.eye(m) if R is None else weight_matrix("R", R, m)
    if np.linalg.eigvalsh(Qm).min() < -1e-12:
        raise SystemDefinitionError("Q must be positive semidefinite")
    if np.linalg.eigvalsh(Rm).min() <= 0:
        raise SystemDefinitionError("R must be positive definite")
    return x0v, Qm, Rm


def _names(
    state_names: Sequence[str], input_names: Sequence[str], n: int, m: int
) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The states' and inputs' names (default ``x1..xn``, ``u1..um``), checked."""
    try:
        names = tuple(state_names) or tuple(f"x{i + 1}" for i in range(n))
        inames = tuple(input_names) or tuple(f"u{i + 1}" for i in range(m))
    except TypeError:
        raise SystemDefinitionError("state_names and input_names must be sequences of texts") from None
    if len(names) != n or len(inames) != m or not all(isinstance(x, str) for x in names + inames):
        raise SystemDefinitionError(f"state_names must have {n} and input_names {m} entries (texts)")
    return names, inames
