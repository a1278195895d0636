"""Riccati machinery of the MPC: the DARE (single and batched) and the unconstrained LQ solution.

* :func:`dare_stabilizing` -- scipy's DARE for one model, checked to be stabilizing.
* :func:`dare_batch` -- the same for many models at once, by structure-preserving
  doubling with batched numpy (used for the terminal weights of a sweep's models).
* :func:`lq_parts` -- the finite-horizon backward recursion (with an affine term
  for the reference) and the affine prediction map of the unconstrained optimum:
  the MPC's exact fast path.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from .errors import MPCFailure

__all__ = ["dare_stabilizing", "dare_batch", "lq_parts"]


def dare_stabilizing(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Stabilizing solution of the DARE for ``(A, B, Q, R)``.

    Raises
    ------
    MPCFailure (kind "dare")
        If there is none (e.g. an identified model that is not stabilizable).
    """
    try:
        with np.errstate(all="ignore"):
            X = sla.solve_discrete_are(A, B, Q, R)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise MPCFailure("dare", f"DARE has no stabilizing solution for the identified model ({exc})") from None
    if not np.all(np.isfinite(X)):
        raise MPCFailure("dare", "DARE has no stabilizing solution for the identified model")
    X = (X + X.T) / 2
    try:
        with np.errstate(all="ignore"):
            K = np.linalg.solve(R + B.T @ X @ B, B.T @ X @ A)
            stabilizing = np.abs(np.linalg.eigvals(A - B @ K)).max() < 1.0 and np.linalg.eigvalsh(X).min() >= -1e-9
    except (np.linalg.LinAlgError, ValueError):  # singular R + B'XB, or non-finite gains
        stabilizing = False
    if not stabilizing:
        raise MPCFailure("dare", "DARE solution is not stabilizing for the identified model")
    return X


def dare_batch(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray, tol: float = 1e-13,
               max_iter: int = 80) -> tuple[np.ndarray, np.ndarray]:
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


def lq_parts(A, B, Q, R, Qf, r, N, u_max, x_max=None, xf_max=None) -> dict:
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
    dict with K (L,N,m,n), kf (L,N,m), P0 (L,n,n), p0 (L,n), c0 (L,), F (L,rows,n), f (L,rows), bound (rows,)
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
    Mx = np.broadcast_to(np.eye(n), (L, n, n))
    mx = np.zeros((L, n))
    Fu, fu, Fx, fx = [], [], [], []
    for k in range(N):
        Fk = -K[:, k] @ Mx
        fk = -np.einsum("lij,lj->li", K[:, k], mx) - kf[:, k]
        Mx = A @ Mx + B @ Fk
        mx = np.einsum("lij,lj->li", A, mx) + np.einsum("lij,lj->li", B, fk)
        Fu.append(Fk)
        fu.append(fk)
        Fx.append(Mx)
        fx.append(mx)
    F, f, bound = list(Fu), list(fu), [np.asarray(u_max, dtype=float)] * N
    if x_max is not None or xf_max is not None:
        big = np.full(n, np.inf)
        boxes = [np.asarray(x_max, dtype=float) if x_max is not None else big for _ in range(N)]
        if xf_max is not None:
            boxes[-1] = np.minimum(boxes[-1], xf_max)
        F += Fx
        f += fx
        bound += boxes
    return dict(K=K, kf=kf, P0=P, p0=p, c0=c, F=np.concatenate(F, axis=1), f=np.concatenate(f, axis=1),
                bound=np.concatenate(bound))
