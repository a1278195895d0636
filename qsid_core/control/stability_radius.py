"""Stability radii of a closed loop and the small-gain test of a gain designed on a model.

* :func:`complex_stability_radius` -- the smallest unstructured complex
  perturbation ``E`` (spectral norm) that makes ``M + E`` unstable:
  ``min over |z| = 1 of sigma_min(zI - M)``. ``||E||_2`` below it certifies
  stability (small-gain theorem; Hinrichsen & Pritchard, *Mathematical Systems
  Theory I*, Springer 2005, Sec. 5.3);
* :func:`small_gain_margin` -- that test for the gain ``K^`` designed on ``(A^, B^)`` and
  applied to the true plant ``(A, B)``; :func:`small_gain_holds` decides it for a batch.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "complex_stability_radii",
    "complex_stability_radius",
    "small_gain_holds",
    "small_gain_margin",
    "small_gain_margins",
]


def complex_stability_radius(M: np.ndarray, grid: int = 180) -> float:
    """``min over |z| = 1 of sigma_min(zI - M)``: the complex stability radius of a stable ``M``.

    ``M + E`` is stable for every complex ``E`` with ``||E||_2`` below it (and some
    ``E`` of that norm makes it unstable). 0 when ``M`` is not stable. One matrix of
    :func:`complex_stability_radii`, which says how it is computed.

    Parameters
    ----------
    M : ndarray, shape (n, n)
    grid : int

    Returns
    -------
    float
    """
    M = np.asarray(M, dtype=float)
    return float(complex_stability_radii(M[None], grid)[0])


#: The refinement in :func:`complex_stability_radii` stops when every bracket is this narrow (in radians).
_THETA_TOL = 1e-12


def complex_stability_radii(M: np.ndarray, grid: int = 180) -> np.ndarray:
    """:func:`complex_stability_radius` of each matrix of a batch, shape (L, n, n) -> (L,).

    Computed on a grid of ``grid`` points of the half circle (``sigma_min`` is even in the angle for a
    real ``M``) joined with the eigenvalues' angles, where the dips sit; then every dip of the grid that
    can hold the minimum is refined by golden-section search between its neighbours, all dips of all
    matrices at once. ``sigma_min`` is 1-Lipschitz along the circle, so a dip whose value exceeds the
    grid's least by more than half the spacing cannot hold the minimum. The result is exact to about
    1e-10 relative for the small systems here (the refinement, not the grid, sets the accuracy).
    0 where a matrix is not stable or not finite.
    """
    M = np.asarray(M, dtype=float)
    L, n = M.shape[0], M.shape[-1]
    out = np.zeros(L)
    idx = np.flatnonzero(np.all(np.isfinite(M.reshape(L, -1)), axis=1))
    if not idx.size:
        return out
    lam = np.linalg.eigvals(M[idx])
    keep = np.abs(lam).max(axis=1) < 1.0
    idx, lam, Ms = idx[keep], lam[keep], M[idx[keep]]
    if not idx.size:
        return out
    eye = np.eye(n)

    def smin(which: np.ndarray, theta: np.ndarray) -> np.ndarray:  # sigma_min(e^(i theta) I - M[which])
        z = np.exp(1j * theta)[..., None, None]
        return np.linalg.svd(z * eye - Ms[which], compute_uv=False)[..., -1]

    base = np.broadcast_to(np.linspace(0.0, np.pi, grid + 1), (idx.size, grid + 1))
    th = np.sort(np.concatenate([base, np.abs(np.angle(lam))], axis=1), axis=1)
    vals = smin(np.arange(idx.size)[:, None], th)
    best = vals.min(axis=1)
    # neighbours across the ends mirror (sigma_min is even in theta and 2 pi periodic); an eigenvalue's
    # angle equal to a grid point repeats it, which only refines one dip twice
    left = np.concatenate([vals[:, 1:2], vals[:, :-1]], axis=1)
    right = np.concatenate([vals[:, 1:], vals[:, -2:-1]], axis=1)
    dips = (vals <= left) & (vals <= right) & (vals - np.pi / grid / 2 < best[:, None])
    which, k = np.nonzero(dips)
    last = th.shape[1] - 1
    lo, hi = th[which, np.maximum(k - 1, 0)], th[which, np.minimum(k + 1, last)]
    g = (np.sqrt(5.0) - 1.0) / 2.0
    c, d = hi - g * (hi - lo), lo + g * (hi - lo)
    fc, fd = smin(which, c), smin(which, d)
    found = np.minimum(fc, fd)
    for _ in range(200):  # each step shrinks every bracket by 0.618: ~50 steps from the grid's spacing
        if float((hi - lo).max()) <= _THETA_TOL:  # (every matrix has a dip: its grid minimum)
            break
        left_side = fc < fd  # the minimum lies in [lo, d]: d becomes the right end
        hi = np.where(left_side, d, hi)
        lo = np.where(left_side, lo, c)
        c, d = np.where(left_side, hi - g * (hi - lo), d), np.where(left_side, c, lo + g * (hi - lo))
        new = smin(which, np.where(left_side, c, d))
        fc, fd = np.where(left_side, new, fd), np.where(left_side, fc, new)
        found = np.minimum(found, new)
    np.minimum.at(best, which, found)
    out[idx] = best
    return out


#: Points of the first grid of the half circle in :func:`small_gain_holds` (its arcs are then halved where needed).
_FIRST_GRID = 12


def small_gain_holds(
    A: np.ndarray, B: np.ndarray, A_hat: np.ndarray, B_hat: np.ndarray, K: np.ndarray, grid: int = 720
) -> np.ndarray:
    """Whether :func:`small_gain_margin`'s test certifies each loop of a batch, decided cheaply where it can be.

    Before any grid, ``r_C <= 1 - rho(M)`` rejects the loops whose perturbation is at least that, and
    ``r_C >= (1 - rho(M)) / cond(V)`` (Bauer-Fike, ``V`` the eigenvectors of ``M``) certifies those whose
    perturbation is below that. Then
    ``sigma_min(zI - M)`` is 1-Lipschitz along the unit circle: on an arc of length ``w`` whose ends
    have values ``a`` and ``b`` it is at least ``(a + b - w) / 2``, and ``r_C`` is at most any value it takes.
    So on a coarse grid of the half circle (``_FIRST_GRID`` points) an arc whose bound exceeds the
    perturbation is settled, a point at or below it rejects the loop, and only the other arcs are halved, level
    after level, until they are no wider than the spacing of a grid of ``grid`` points; the few loops still
    open are refined exactly (:func:`complex_stability_radius`). Every decision is the exact test's: the
    bounds only decide where they are conclusive.

    Parameters
    ----------
    A : ndarray, shape (n, n); B : ndarray, shape (n, m)
        The true plant.
    A_hat : ndarray, shape (L, n, n); B_hat : ndarray, shape (L, n, m); K : ndarray, shape (L, m, n)
        Models and the gains designed on them.
    grid : int
        The finest arcs are ``pi / grid`` wide at most; also the exact refinement's grid.

    Returns
    -------
    ndarray of bool, shape (L,)
    """
    E, M = _loop_error(A, B, A_hat, B_hat, K)
    L = E.shape[0]
    out = np.zeros(L, dtype=bool)
    fin = np.all(np.isfinite(E.reshape(L, -1)), axis=1) & np.all(np.isfinite(M.reshape(L, -1)), axis=1)
    todo = np.flatnonzero(fin)
    if not todo.size:
        return out
    lam, V = np.linalg.eig(M[todo])
    rho = np.full(L, np.inf)
    rho[todo] = np.abs(lam).max(axis=1)
    keep = rho[todo] < 1.0
    todo, V = todo[keep], V[keep]
    pert = np.full(L, np.inf)
    if todo.size:
        pert[todo] = np.linalg.norm(E[todo], 2, axis=(1, 2))
    # r_C(M) <= 1 - rho(M): moving the largest eigenvalue radially onto the circle is a perturbation of that
    # norm. A loop whose perturbation is at least that is not certified, with no frequency sweep.
    keep = pert[todo] < 1.0 - rho[todo]
    todo, V = todo[keep], V[keep]
    if not todo.size:
        return out
    # r_C(M) >= (1 - rho(M)) / cond(V) (Bauer-Fike: (zI - M)^-1 = V (zI - diag(lam))^-1 V^-1 and every
    # |z - lam_i| >= 1 - rho on the circle), V the eigenvectors: a loop whose perturbation is below that is
    # certified, with no frequency sweep (a defective M has cond(V) huge, so it goes on to the sweep).
    with np.errstate(all="ignore"):
        kappa = np.linalg.cond(V)
    sure = np.isfinite(kappa) & (pert[todo] < (1.0 - rho[todo]) / kappa * (1.0 - 1e-9))
    out[todo[sure]] = True
    todo = todo[~sure]
    if todo.size:
        out[todo] = _below_radius(M[todo], pert[todo], grid)
    return out


def _below_radius(M: np.ndarray, pert: np.ndarray, grid: int) -> np.ndarray:
    """``pert < r_C(M)`` per loop (``M`` shape (L, n, n) stable, ``pert`` shape (L,)), decided on arcs of the
    half circle as :func:`small_gain_holds` describes; shape (L,) bool."""
    L, n, _ = M.shape
    eye = np.eye(n)

    def smin(loop: np.ndarray, theta: np.ndarray) -> np.ndarray:  # sigma_min(e^(i theta) I - M[loop]), elementwise
        return np.linalg.svd(np.exp(1j * theta)[..., None, None] * eye - M[loop], compute_uv=False)[..., -1]

    th = np.linspace(0.0, np.pi, _FIRST_GRID + 1)
    vals = smin(np.arange(L)[:, None], th[None, :])
    low: np.ndarray = np.any(vals <= pert[:, None], axis=1)  # a value at or below the perturbation: r_C is too
    # the open arcs: their loop, left end, the values at both ends; all of width w
    loop, left = np.repeat(np.arange(L), _FIRST_GRID), np.tile(th[:-1], L)
    a, b, w = vals[:, :-1].ravel(), vals[:, 1:].ravel(), float(th[1])
    while True:
        keep = ~low[loop] & ((a + b - w) / 2 <= pert[loop])  # an arc that can still dip to the perturbation
        loop, left, a, b = loop[keep], left[keep], a[keep], b[keep]
        if not loop.size or w <= np.pi / grid:
            break
        w /= 2
        mid = smin(loop, left + w)
        low[loop[mid <= pert[loop]]] = True
        loop, left, a, b = np.r_[loop, loop], np.r_[left, left + w], np.r_[a, mid], np.r_[mid, b]
    out: np.ndarray = ~low
    still = np.unique(loop)  # arcs as fine as the grid and still open: the radius itself
    if still.size:
        out[still] = pert[still] < complex_stability_radii(M[still], grid)
    return out


def small_gain_margin(
    A: np.ndarray, B: np.ndarray, A_hat: np.ndarray, B_hat: np.ndarray, K: np.ndarray
) -> tuple[float, float]:
    """The robust-stability test of the gain ``K`` designed on ``(A^, B^)`` and applied to ``(A, B)``.

    The true closed loop is ``A - B K = (A^ - B^ K) + (dA - dB K)`` with
    ``dA = A - A^``, ``dB = B - B^``. By the small-gain theorem it is stable when
    ``||dA - dB K||_2 < r_C(A^ - B^ K)``, the complex stability radius of the
    nominal loop (:func:`complex_stability_radius`). A sufficient condition only:
    it ignores the structure of the perturbation.

    Returns
    -------
    (perturbation, radius) : floats ``||dA - dB K||_2`` and ``r_C(A^ - B^ K)``;
        the loop is certified when ``perturbation < radius``.
    """
    pert, rad = small_gain_margins(
        A, B, np.asarray(A_hat, float)[None], np.asarray(B_hat, float)[None], np.asarray(K, float)[None]
    )
    return float(pert[0]), float(rad[0])


def small_gain_margins(
    A: np.ndarray, B: np.ndarray, A_hat: np.ndarray, B_hat: np.ndarray, K: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`small_gain_margin` for a batch: ``A_hat`` (L, n, n), ``B_hat`` (L, n, m), ``K`` (L, m, n) ->
    ``(perturbation, radius)``, each shape (L,) (perturbation ``inf`` where it is not finite)."""
    E, M = _loop_error(A, B, A_hat, B_hat, K)
    L = E.shape[0]
    pert = np.full(L, np.inf)
    fin = np.all(np.isfinite(E.reshape(L, -1)), axis=1)
    if fin.any():
        pert[fin] = np.linalg.norm(E[fin], 2, axis=(1, 2))
    return pert, complex_stability_radii(M)


def _loop_error(
    A: np.ndarray, B: np.ndarray, A_hat: np.ndarray, B_hat: np.ndarray, K: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``(E, M)`` of a batch: the perturbation ``(A - A^) - (B - B^) K`` and the nominal loop ``A^ - B^ K``,
    each shape (L, n, n) (non-finite where the inputs are)."""
    A_hat, B_hat, K = (np.asarray(v, dtype=float) for v in (A_hat, B_hat, K))
    with np.errstate(all="ignore"):
        return (np.asarray(A, float) - A_hat) - (np.asarray(B, float) - B_hat) @ K, A_hat - B_hat @ K
