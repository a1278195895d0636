"""Riccati machinery of the MPC: the DARE (single and batched) and the unconstrained LQ solution.

* :func:`dare_stabilizing` -- scipy's DARE for one model, checked to be stabilizing.
* :func:`dare_batch` -- the same for many models at once, by structure-preserving
  doubling with batched numpy (used for the terminal weights of a sweep's models).
* :func:`lq_parts` -- the finite-horizon backward recursion (with an affine term
  for the reference) and the affine prediction map of the unconstrained optimum:
  the MPC's exact fast path.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
from numpy.typing import ArrayLike

from ..errors import FailureKind, MPCFailure

__all__ = ["dare_stabilizing", "dare_batch", "dare_many", "lq_parts", "LQParts", "state_box"]


def dare_stabilizing(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Stabilizing solution of the DARE for ``(A, B, Q, R)``.

    Raises
    ------
    MPCFailure (kind "dare")
        If there is none (e.g. an identified model that is not stabilizable).
    """
    try:
        with np.errstate(all="ignore"):
            X: np.ndarray = sla.solve_discrete_are(A, B, Q, R)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise MPCFailure(
            FailureKind.DARE, f"DARE has no stabilizing solution for the identified model ({exc})"
        ) from None
    if not np.all(np.isfinite(X)):
        raise MPCFailure(FailureKind.DARE, "DARE has no stabilizing solution for the identified model")
    X = (X + X.T) / 2
    try:
        with np.errstate(all="ignore"):
            K = np.linalg.solve(R + B.T @ X @ B, B.T @ X @ A)
            stabilizing = np.abs(np.linalg.eigvals(A - B @ K)).max() < 1.0 and np.linalg.eigvalsh(X).min() >= -1e-9
    except (np.linalg.LinAlgError, ValueError):  # singular R + B'XB, or non-finite gains
        stabilizing = False
    if not stabilizing:
        raise MPCFailure(FailureKind.DARE, "DARE solution is not stabilizing for the identified model")
    return X


def dare_batch(
    A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray, tol: float = 1e-13, max_iter: int = 80
) -> tuple[np.ndarray, np.ndarray]:
    """Stabilizing DARE solutions for a batch of models, by structure-preserving doubling.

    Parameters
    ----------
    A : ndarray, shape (L, n, n)
    B : ndarray, shape (L, n, m)
    Q : ndarray, shape (n, n)
    R : ndarray, shape (m, m), positive definite

    Returns
    -------
    X : ndarray, shape (L, n, n)
        The solutions (NaN where ``ok`` is False).
    ok : ndarray of bool, shape (L,)
        Converged, finite and stabilizing (spectral radius of ``A - B K`` below 1).
        Callers fall back to :func:`dare_stabilizing` where it is False.

    Notes
    -----
    SDA (Chu, Fan, Lin 2005): ``A_0 = A``, ``G_0 = B R^-1 B'``, ``H_0 = Q``;
    ``W = I + G_k H_k``; ``A_{k+1} = A_k W^-1 A_k``, ``G_{k+1} = G_k + A_k W^-1 G_k A_k'``,
    ``H_{k+1} = H_k + A_k' H_k W^-1 A_k``; ``H_k`` converges quadratically to the
    stabilizing solution. All models are iterated together with batched numpy.
    """
    L, n, _ = A.shape
    Ak = np.array(A, dtype=float)
    G = B @ np.linalg.solve(R, np.swapaxes(B, 1, 2))
    H = np.broadcast_to(np.asarray(Q, dtype=float), (L, n, n)).copy()
    I = np.eye(n)
    done = np.zeros(L, dtype=bool)
    with np.errstate(all="ignore"):
        for _ in range(max_iter):
            W = I + G @ H
            try:
                WiA = np.linalg.solve(W, Ak)
                WiG = np.linalg.solve(W, G)
            except np.linalg.LinAlgError:
                break
            Hn = H + np.swapaxes(Ak, 1, 2) @ H @ WiA
            G = G + Ak @ WiG @ np.swapaxes(Ak, 1, 2)
            Ak = Ak @ WiA
            delta = np.abs(Hn - H).max(axis=(1, 2))
            scale = np.abs(Hn).max(axis=(1, 2))
            H = Hn
            done = np.isfinite(delta) & (delta <= tol * np.maximum(scale, 1.0))
            if done.all():
                break
        X = (H + np.swapaxes(H, 1, 2)) / 2
        ok = done & np.all(np.isfinite(X), axis=(1, 2))
        if ok.any():
            Bt = np.swapaxes(B, 1, 2)
            try:
                K = np.linalg.solve(R + Bt @ X @ B, Bt @ X @ A)
                Acl = np.where(ok[:, None, None], A - B @ K, 0.0)
                rho = np.abs(np.linalg.eigvals(Acl)).max(axis=1)
                ok &= rho < 1.0
            except (np.linalg.LinAlgError, ValueError):  # one singular/non-finite model spoils the batch:
                ok[:] = False  # leave every model to the callers' per-model fallback (dare_stabilizing)
    X[~ok] = np.nan
    return X, ok


def dare_many(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Stabilizing DARE solutions for a batch of models: :func:`dare_batch`, and :func:`dare_stabilizing`
    for the models doubling does not settle.

    Parameters
    ----------
    A : ndarray, shape (L, n, n); B : ndarray, shape (L, n, m); Q : (n, n); R : (m, m)

    Returns
    -------
    X : ndarray, shape (L, n, n)
        The solutions (NaN where ``ok`` is False).
    ok : ndarray of bool, shape (L,)
        False where neither method finds a stabilizing solution.
    """
    X, ok = dare_batch(A, B, Q, R)
    for k in np.flatnonzero(~ok).tolist():
        try:
            X[k] = dare_stabilizing(A[k], B[k], Q, R)
            ok[k] = True
        except MPCFailure:
            pass
    return X, ok


def _solve_each(S: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``S^-1 rhs`` for a batch; a singular ``S`` gives NaN for its model only (not a LinAlgError for all)."""
    try:
        return np.linalg.solve(S, rhs)
    except np.linalg.LinAlgError:
        out = np.full(rhs.shape, np.nan)
        for i in range(S.shape[0]):
            try:
                out[i] = np.linalg.solve(S[i], rhs[i])
            except np.linalg.LinAlgError:
                pass
        return out


def state_box(n: int, N: int, x_max: ArrayLike | None = None, xf_max: ArrayLike | None = None) -> np.ndarray | None:
    """Half-widths of the box on the predicted states ``x_1..x_N``, shape (N*n,), or None.

    ``x_max`` (shape (n,)) bounds every ``x_k``, ``xf_max`` (shape (n,)) the terminal
    ``x_N`` as well; ``inf`` where a state is unbounded. Never on the measured ``x_0``.
    """
    if x_max is None and xf_max is None:
        return None
    boxes = np.tile(np.full(n, np.inf) if x_max is None else np.asarray(x_max, dtype=float), (N, 1))
    if xf_max is not None:
        boxes[-1] = np.minimum(boxes[-1], np.asarray(xf_max, dtype=float))
    return boxes.reshape(-1)


@dataclass(frozen=True)
class LQParts:
    """Unconstrained finite-horizon LQ solution of ``L`` models (the MPC's exact fast path).

    Index ``[k]`` of the leading axis is model ``k`` (see :meth:`model`); ``rows`` is
    ``N*m`` (predicted inputs) plus ``N*n`` (predicted states) when a state or
    terminal box is set. Units: inputs, states and cost as in the system.

    Attributes
    ----------
    K : ndarray, shape (L, N, m, n)
        Feedback gains, ``u_k = -K_k x_k - kf_k``.
    kf : ndarray, shape (L, N, m)
        Affine terms from the reference.
    P0 : ndarray, shape (L, n, n)
        Quadratic term of the optimal cost ``V_0(x) = x'P0 x + 2 p0'x + c0``.
    p0 : ndarray, shape (L, n)
    c0 : ndarray, shape (L,)
    F : ndarray, shape (L, rows, n)
        Prediction map ``z = F x0 + f`` of the constrained quantities ``u_0..u_{N-1}`` [, ``x_1..x_N``].
    f : ndarray, shape (L, rows)
    bound : ndarray, shape (rows,)
        Half-widths of their box (``inf`` where unbounded); the unconstrained optimum
        solves the constrained QP exactly iff ``|F x0 + f| <= bound``.
    """

    K: np.ndarray
    kf: np.ndarray
    P0: np.ndarray
    p0: np.ndarray
    c0: np.ndarray
    F: np.ndarray
    f: np.ndarray
    bound: np.ndarray

    def model(self, k: int) -> LQParts:
        """The parts of model ``k`` alone (leading axis dropped; ``bound`` is shared)."""
        return LQParts(self.K[k], self.kf[k], self.P0[k], self.p0[k], self.c0[k], self.F[k], self.f[k], self.bound)

    def finite(self) -> np.ndarray:
        """Per model (batched parts): True where every part is finite. Shape (L,)."""
        arrays = (self.K, self.kf, self.P0, self.p0, self.c0, self.F, self.f)
        ok: np.ndarray = np.logical_and.reduce([np.isfinite(a.reshape(a.shape[0], -1)).all(axis=1) for a in arrays])
        return ok


def _prediction_maps(
    A: np.ndarray, B: np.ndarray, K: np.ndarray, kf: np.ndarray
) -> tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray], list[np.ndarray]]:
    """``(Fu, fu, Fx, fx)``: per step k the affine maps ``u_k = Fu[k] x0 + fu[k]`` and ``x_{k+1} = Fx[k] x0 + fx[k]``
    of the law ``u_k = -K_k x_k - kf_k`` (shapes (L, m, n), (L, m), (L, n, n), (L, n))."""
    L, n, _ = B.shape
    Mx = np.broadcast_to(np.eye(n), (L, n, n))
    mx = np.zeros((L, n))
    Fu, fu, Fx, fx = [], [], [], []
    for k in range(K.shape[1]):
        Fk = -K[:, k] @ Mx
        fk = -np.einsum("lij,lj->li", K[:, k], mx) - kf[:, k]
        Mx = A @ Mx + B @ Fk
        mx = np.einsum("lij,lj->li", A, mx) + np.einsum("lij,lj->li", B, fk)
        Fu.append(Fk)
        fu.append(fk)
        Fx.append(Mx)
        fx.append(mx)
    return Fu, fu, Fx, fx


def lq_parts(
    A: np.ndarray,
    B: np.ndarray,
    Q: np.ndarray,
    R: np.ndarray,
    Qf: np.ndarray,
    r: np.ndarray,
    N: int,
    u_max: np.ndarray,
    x_max: np.ndarray | None = None,
    xf_max: np.ndarray | None = None,
) -> LQParts:
    """Unconstrained finite-horizon LQ solution for a batch of models (the MPC's fast path).

    Backward Riccati recursion with an affine term for the reference ``r``:
    ``u_k = -K_k x_k - kf_k``; ``V_0(x) = x'P0x + 2 p0'x + c0``. Then the affine map
    ``z = F x0 + f`` from the initial state to the predicted inputs ``u_0..u_{N-1}``
    (and, with a state or terminal box, states ``x_1..x_N``) with the box
    half-widths ``bound``: the unconstrained optimum solves the constrained QP
    exactly iff ``|F x0 + f| <= bound``.

    Parameters
    ----------
    A : (L, n, n), B : (L, n, m), Qf : (L, n, n)
        Models and terminal weights.
    Q : (n, n), R : (m, m), r : (n,)
    N : int
        Horizon.
    u_max : (m,); x_max, xf_max : (n,) or None

    Returns
    -------
    LQParts
    """
    L, n, m = B.shape
    At, Bt = np.swapaxes(A, 1, 2), np.swapaxes(B, 1, 2)
    P = np.array(Qf, dtype=float)
    p = -(P @ r)
    c = np.einsum("i,lij,j->l", r, P, r)
    rQr = float(r @ Q @ r)
    K = np.empty((L, N, m, n))
    kf = np.empty((L, N, m))
    for k in range(N - 1, -1, -1):
        BtP = Bt @ P
        S = R + BtP @ B
        Kk = _solve_each(S, BtP @ A)
        Btp = np.einsum("lij,lj->li", Bt, p)
        kk = _solve_each(S, Btp[..., None])[..., 0]
        c = c + rQr - np.einsum("li,li->l", Btp, kk)
        p = -(Q @ r) + np.einsum("lji,lj->li", A - B @ Kk, p)
        P = Q + At @ P @ A - np.swapaxes(BtP @ A, 1, 2) @ Kk
        P = (P + np.swapaxes(P, 1, 2)) / 2
        K[:, k], kf[:, k] = Kk, kk
    Fu, fu, Fx, fx = _prediction_maps(A, B, K, kf)
    F, f, bound = list(Fu), list(fu), [np.asarray(u_max, dtype=float)] * N
    xb = state_box(n, N, x_max, xf_max)
    if xb is not None:
        F += Fx
        f += fx
        bound.append(xb)
    return LQParts(
        K=K,
        kf=kf,
        P0=P,
        p0=p,
        c0=c,
        F=np.concatenate(F, axis=1),
        f=np.concatenate(f, axis=1),
        bound=np.concatenate(bound),
    )
