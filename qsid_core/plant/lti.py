"""The true plant: :class:`LTISystem`, a discrete-time ``x+ = A x + B u`` with its regulation task.

Validated on construction (shapes, finite entries, ``Q`` positive semidefinite,
``R`` positive definite); an uncontrollable ``(A, B)`` warns with
:class:`UncontrollableWarning`. Presets and system files: :mod:`qsid_core.plant.systems`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import ConfigError, SystemDefinitionError, check_float, short_repr
from ..validate import MAX_MAGNITUDE, as_float_array, as_matrix, check_text, weight_matrix

__all__ = ["LTISystem", "UncontrollableWarning", "MAX_STATES", "MAX_INPUTS"]


class UncontrollableWarning(UserWarning):
    """(A, B) is not controllable: identification works, MPC may not regulate."""


#: Largest number of states / inputs of a system (the controllability test builds an n x n*m matrix).
MAX_STATES = 100
MAX_INPUTS = 100


@dataclass(frozen=True, eq=False)
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
    A: np.ndarray
    B: np.ndarray
    x0: np.ndarray | None = None
    Q: np.ndarray | None = None
    R: np.ndarray | None = None
    dt: float = 1.0
    description: str = ""
    state_names: tuple[str, ...] = field(default=())
    input_names: tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        check_text("system name", self.name, SystemDefinitionError)
        check_text("description", self.description, SystemDefinitionError)
        try:
            object.__setattr__(self, "dt", check_float("dt", self.dt, 0.0, lo_open=True))
        except ConfigError:
            raise SystemDefinitionError(
                f"dt (the sample time) must be a positive, finite number of seconds; got {short_repr(self.dt)}"
            ) from None
        A = as_matrix("A", self.A, (None, None))
        n = A.shape[0]
        if A.shape != (n, n):
            raise SystemDefinitionError(f"A must be square; got shape {A.shape}")
        if n > MAX_STATES:
            raise SystemDefinitionError(f"A: at most {MAX_STATES} states; got {n}")
        B = as_matrix("B", self.B, (n, None))
        m = B.shape[1]
        if m > MAX_INPUTS:
            raise SystemDefinitionError(f"B: at most {MAX_INPUTS} inputs; got {m}")
        if max(np.abs(A).max(), np.abs(B).max()) < 1.0 / MAX_MAGNITUDE:
            raise SystemDefinitionError(
                f"A and B are both (nearly) all zeros (every entry below {1.0 / MAX_MAGNITUDE:g} in magnitude): "
                "there is nothing to identify and relative model errors are undefined"
            )
        if self.x0 is None:
            x0 = np.eye(n)[0]
        else:
            x0 = as_float_array(
                "x0", self.x0, ndim_max=2, error=SystemDefinitionError, what=f"a list of {n} numbers"
            ).reshape(-1)
        if x0.shape != (n,):
            raise SystemDefinitionError(f"x0 must be {n} finite numbers; got {short_repr(self.x0)}")
        Q = np.eye(n) if self.Q is None else weight_matrix("Q", self.Q, n)
        R = np.eye(m) if self.R is None else weight_matrix("R", self.R, m)
        if np.linalg.eigvalsh(Q).min() < -1e-12:
            raise SystemDefinitionError("Q must be positive semidefinite")
        if np.linalg.eigvalsh(R).min() <= 0:
            raise SystemDefinitionError("R must be positive definite")
        for arr in (A, B, x0, Q, R):
            arr.setflags(write=False)
        object.__setattr__(self, "A", A)
        object.__setattr__(self, "B", B)
        object.__setattr__(self, "x0", x0)
        object.__setattr__(self, "Q", Q)
        object.__setattr__(self, "R", R)
        try:
            names = tuple(self.state_names) or tuple(f"x{i + 1}" for i in range(n))
            inames = tuple(self.input_names) or tuple(f"u{i + 1}" for i in range(m))
        except TypeError:
            raise SystemDefinitionError("state_names and input_names must be sequences of texts") from None
        if len(names) != n or len(inames) != m or not all(isinstance(x, str) for x in names + inames):
            raise SystemDefinitionError(f"state_names must have {n} and input_names {m} entries (texts)")
        object.__setattr__(self, "state_names", names)
        object.__setattr__(self, "input_names", inames)
        if not self.controllable:
            warnings.warn(
                f"system {self.name!r}: (A, B) is not controllable (rank of the controllability "
                f"matrix {self.controllability_rank} < n = {n}); MPC may fail to regulate",
                UncontrollableWarning,
                stacklevel=3,
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
        """Rank of the controllability matrix ``[B, AB, ..., A^(n-1) B]`` (python-control's ``ctrb``; built
        here with numpy, so building a system never imports python-control, ~2-5 s)."""
        # scaling A and B by positive numbers leaves the rank unchanged and keeps A^k from overflowing
        a = np.abs(self.A).max()
        A = self.A / a if a > 1.0 else self.A
        blocks = [self.B]
        for _ in range(self.n - 1):
            blocks.append(A @ blocks[-1])
        C = np.hstack(blocks)
        try:
            return int(np.linalg.matrix_rank(C, tol=1e-9 * max(1.0, np.abs(C).max())))
        except np.linalg.LinAlgError:  # the SVD did not converge: badly scaled (A, B)
            raise SystemDefinitionError(
                "cannot decide whether (A, B) is controllable: the controllability matrix is too badly scaled"
            ) from None

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
            "x0": np.asarray(self.x0).tolist(),  # never None after __post_init__
            "Q": np.asarray(self.Q).tolist(),
            "R": np.asarray(self.R).tolist(),
            "dt": self.dt,
        }
