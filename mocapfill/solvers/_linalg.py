"""Numerical building blocks shared by the completion methods.

- :func:`soft_threshold` — entrywise shrinkage, the proximal map of ``tau·‖·‖₁``.
- :func:`svt` — singular value thresholding, the proximal map of ``tau·‖·‖_*``
  (Cai, Candès & Shen 2010, eq. 2.2).
- :func:`second_difference_matrix`, :func:`second_difference_eigenvalues`,
  :func:`temporal_solve` — the temporal-stability term ``(mu/2)·‖X Tᵀ‖_F²`` with ``T`` the
  second difference along time under Neumann (reflecting) boundary conditions:
  ``T`` is the n×n matrix with rows ``[1, -1, 0, ...]``, ``[..., 1, -2, 1, ...]``,
  ``[..., 0, -1, 1]``. ``T`` is symmetric and diagonalised by the orthonormal DCT-II
  matrix ``C``: ``T = Cᵀ diag(-4 sin²(iπ/(2n))) C``, hence
  ``TᵀT = Cᵀ diag(16 sin⁴(iπ/(2n))) C``, i = 0..n-1.
- :func:`linear_fill` — row-wise linear interpolation along time, ends held.
- :func:`spd_inverse`, :func:`times_spd_inverse` — the inverse of a symmetric positive
  definite matrix by Cholesky, and the product with it.
- :func:`pair_distances` — mean and spread over time of the distance between every two
  markers, on the frames where both are observed (:func:`distance_rows`: from some
  markers to some others; :func:`nearest_markers`: each marker's nearest).
- :func:`simplex_least_squares` — the convex weights minimising a Gram matrix's quadratic
  form, for the blend (without ``scipy.optimize``, whose import cost 0.1 s).

Nothing here modifies its inputs.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np


def as_problem(matrix: np.ndarray, observed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Validate a solver's inputs: float64 (m, n) data and a bool mask of the same shape."""
    matrix = np.asarray(matrix, dtype=np.float64)
    observed = np.asarray(observed, dtype=bool)
    if matrix.ndim != 2 or observed.shape != matrix.shape:
        raise ValueError(
            f"matrix and observed must be 2-D of equal shape, got {matrix.shape} and "
            f"{observed.shape}")
    return matrix, observed


def iteration_dtype(dtype) -> np.dtype:
    """``dtype`` as a numpy dtype, which must be float32 or float64 (the floating types
    the solvers' iterations run in)."""
    dtype = np.dtype(dtype)
    if dtype not in (np.float32, np.float64):
        raise ValueError(f"dtype must be float32 or float64, got {dtype}")
    return dtype


def soft_threshold(x: np.ndarray, tau: float | np.ndarray) -> np.ndarray:
    """``sign(x)·max(|x| - tau, 0)`` entrywise (a new array)."""
    x = np.asarray(x, dtype=np.float64)
    return np.sign(x) * np.maximum(np.abs(x) - tau, 0.0)


def _floating(x: np.ndarray) -> np.ndarray:
    x = np.asarray(x)
    return x if x.dtype in (np.float32, np.float64) else x.astype(np.float64)


def svt(x: np.ndarray, tau: float) -> tuple[np.ndarray, int]:
    """Singular value thresholding ``D_tau(x) = U diag(max(σ - tau, 0)) Vᵀ``.

    Returns the shrunk matrix (in x's floating type: float32 stays float32) and its rank
    (the number of singular values above ``tau``).

    A wide or tall matrix (one side at least ``_GRAM_ASPECT`` times the other: a mocap
    matrix, 3·markers × frames) is shrunk through the eigendecomposition of its small Gram
    matrix instead, ``D_tau(x) = U diag(max(σ − tau, 0)/σ) Uᵀ x`` with ``x xᵀ = U diag(σ²) Uᵀ``:
    123 × 4000 float64 in 7–8 against 46 ms for the SVD (one thread), which was a TSMC
    iteration's main cost.
    The squared singular values carry an absolute rounding of about 1e−16·σ₁²; the
    shrunk matrix agrees with the SVD's to about 1e−9 of its norm on such matrices.
    """
    x = _floating(x)
    m, n = x.shape
    if min(m, n) * _GRAM_ASPECT <= max(m, n):
        return _gram_svt(x, tau)
    u, s, vt = np.linalg.svd(x, full_matrices=False)
    s = s - tau
    rank = int(np.count_nonzero(s > 0))
    if rank == 0:
        return np.zeros_like(x), 0
    return (u[:, :rank] * s[:rank]) @ vt[:rank], rank


# Aspect ratio from which :func:`svt` goes through the Gram matrix of the short side.
_GRAM_ASPECT = 4


def _gram_svt(x: np.ndarray, tau: float) -> tuple[np.ndarray, int]:
    wide = x.shape[0] <= x.shape[1]
    short = x if wide else x.T
    # A float32 x (TSMC's candidate in the default) is shrunk in float32, but its small
    # Gram matrix is formed and decomposed in float64: formed in float32, it holds the
    # squared singular values only to about 1e−7·σ₁², which loses every σ below about
    # 3e−4·σ₁ (on 10_01, 78 of the 93 kept in float64).
    short64 = short.astype(np.float64, copy=False)
    values, u = np.linalg.eigh(short64 @ short64.T)              # ascending
    sigma = np.sqrt(np.maximum(values, 0.0))
    keep = sigma > tau
    rank = int(np.count_nonzero(keep))
    if rank == 0:
        return np.zeros_like(x), 0
    u = u[:, keep]
    # One product with the whole matrix: the short side's projector, shrunk, times x.
    shrink = ((u * ((sigma[keep] - tau) / sigma[keep])) @ u.T).astype(x.dtype, copy=False)
    return (shrink @ x if wide else x @ shrink), rank


def second_difference_matrix(n: int) -> np.ndarray:
    """The dense n×n Neumann second-difference matrix ``T`` (for tests and small problems)."""
    t = np.zeros((n, n))
    if n < 2:
        return t
    idx = np.arange(n)
    t[idx, idx] = -2.0
    t[idx[:-1], idx[:-1] + 1] = 1.0
    t[idx[1:], idx[1:] - 1] = 1.0
    t[0, 0] = t[-1, -1] = -1.0
    return t


def second_difference_eigenvalues(n: int) -> np.ndarray:
    """Eigenvalues of ``TᵀT`` in DCT-II order: ``16 sin⁴(iπ/(2n))``, i = 0..n-1."""
    i = np.arange(n, dtype=np.float64)
    return 16.0 * np.sin(i * np.pi / (2.0 * n)) ** 4


def temporal_solve(b: np.ndarray, eta: float, mu: float) -> np.ndarray:
    """Solve ``X (eta·I + mu·TᵀT) = B`` for X, i.e. ``X = B Cᵀ Γ C`` with
    ``Γ = diag(1 / (eta + mu·16 sin⁴(iπ/(2n))))``, row-wise via the orthonormal DCT-II.

    ``b`` is (m, n) with time along axis 1 (float32 stays float32); needs ``eta > 0``.
    When n has a large prime factor the FFT behind the DCT is slow (n = 4499 = 11·409:
    72 ms for 123 rows against 3.6 ms at n = 810), and the same system is solved instead
    by a banded Cholesky factorisation of the pentadiagonal ``eta·I + mu·TᵀT`` (17 ms
    there); both agree to 1e−12.
    """
    from ._compiled import dct, idct

    b = _floating(b)
    n = b.shape[-1]
    if n > 64 and _largest_prime_factor(n) > 64:
        return _banded_temporal_solve(b, eta, mu).astype(b.dtype, copy=False)
    gamma = (1.0 / (eta + mu * _cached_eigenvalues(n))).astype(b.dtype)
    # One new array: the DCT's output is scaled and transformed back in place.
    coefficients = dct(b)
    coefficients *= gamma
    return idct(coefficients, overwrite=True)


def fast_length(n: int) -> int:
    """The smallest length ≥ n the DCT handles fast (only 2, 3, 5 as prime factors)."""
    from ._compiled import good_size

    return good_size(n)


def padded_to_fast_length(matrix: np.ndarray, observed: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray]:
    """``matrix`` and ``observed`` with wholly unobserved frames (zeros) appended up to
    :func:`fast_length`; the inputs themselves where none are needed. The values on the
    missing entries are kept as given (the solvers read the observed ones only).

    The temporal step's DCT is slow for lengths with large prime factors (123 rows: 4300 =
    2²·5²·43 takes 10 ms, 4320 = 2⁵·3³·5 3.6 ms; 4499 = 11·409 needs the banded solve);
    the extra frames only move the free end condition of the temporal term past the clip's
    last frame.
    """
    m, n = matrix.shape
    padded = fast_length(n)
    if padded == n:
        return matrix, observed
    big = np.zeros((m, padded))
    big[:, :n] = matrix
    seen = np.zeros((m, padded), dtype=bool)
    seen[:, :n] = observed
    return big, seen


@lru_cache(maxsize=8)
def _cached_eigenvalues(n: int) -> np.ndarray:
    values = second_difference_eigenvalues(n)
    values.flags.writeable = False
    return values


@lru_cache(maxsize=32)
def _largest_prime_factor(n: int) -> int:
    factor, largest = 2, 1
    while factor * factor <= n:
        while n % factor == 0:
            largest, n = factor, n // factor
        factor += 1
    return max(largest, n)


@lru_cache(maxsize=8)
def _second_difference_gram_bands(n: int) -> np.ndarray:
    """The upper bands (3, n) of TᵀT in LAPACK's symmetric-banded layout (n ≥ 4)."""
    main = np.full(n, 6.0)
    main[[0, -1]] = 2.0
    first = np.full(n - 1, -4.0)
    first[[0, -1]] = -3.0
    bands = np.zeros((3, n))
    bands[2] = main
    bands[1, 1:] = first
    bands[0, 2:] = 1.0
    return bands


def _banded_temporal_solve(b: np.ndarray, eta: float, mu: float) -> np.ndarray:
    from ._compiled import solveh_banded

    bands = mu * _second_difference_gram_bands(b.shape[-1])
    bands[2] += eta
    return solveh_banded(bands, b.T).T


def linear_fill(matrix: np.ndarray, observed: np.ndarray) -> np.ndarray:
    """Row-wise linear interpolation of the observed samples along time (axis 1).

    Gaps at either end of a row are held at the nearest observed value; a row with no
    observed sample becomes 0. Returns a new finite float64 array.
    """
    matrix = np.asarray(matrix, dtype=np.float64)
    observed = np.asarray(observed, dtype=bool)
    out = np.where(observed, matrix, 0.0)
    t = np.arange(matrix.shape[1], dtype=np.float64)
    m = matrix.shape[0]
    start = 0
    while start < m:
        # Consecutive rows with one mask (a marker's x, y, z) share its index arrays.
        mask = observed[start]
        stop = start + 1
        while stop < m and np.array_equal(observed[stop], mask):
            stop += 1
        rows, start = range(start, stop), stop
        if mask.all() or not mask.any():
            continue
        missing = np.flatnonzero(~mask)
        present = np.flatnonzero(mask)
        t_missing, t_present = t[missing], t[present]
        for row in rows:
            # np.interp holds the first/last value beyond the data range.
            out[row, missing] = np.interp(t_missing, t_present, matrix[row, present])
    return out


def spd_inverse(A: np.ndarray) -> np.ndarray:
    """Inverse of a symmetric positive definite matrix by Cholesky (LAPACK potrf + potri).

    An explicit inverse is far cheaper than a solve with thousands of right-hand sides;
    the Cholesky route is 2–4× cheaper than ``np.linalg.inv``'s LU (123 × 123 float32:
    about 0.5 against 1–1.8 ms, which was a quarter of an 810-frame iteration). Falls
    back to LU if rounding made A numerically indefinite.
    """
    from ._compiled import lapack

    potrf, potri = lapack("potrf", A), lapack("potri", A)
    factor, info = potrf(A, lower=False, clean=False, overwrite_a=False)
    if info == 0:
        inverse, info = potri(factor, lower=False, overwrite_c=True)
        if info == 0:
            upper = np.triu(inverse)
            return upper + np.triu(upper, 1).T
    return np.linalg.inv(A)


def times_spd_inverse(B: np.ndarray, A: np.ndarray) -> np.ndarray:
    """``B A⁻¹`` for a symmetric positive definite A: with A = UᵀU (LAPACK potrf), two
    triangular solves (BLAS trsm) from the right, B U⁻¹ then (B U⁻¹) U⁻ᵀ.

    At 123 × 123 float32 0.59 ms against 0.67 for potrf + potri + symm (the inverse's
    upper triangle times B) and 1.0 for a general inverse, twice per TrNN iteration; also
    closer to the float64 product (2e−7 against 5e−7 relative). Falls back to LU where A
    is numerically indefinite.
    """
    from ._compiled import blas, lapack

    potrf = lapack("potrf", A)
    factor, info = potrf(A, lower=False, clean=False, overwrite_a=False)
    if info == 0:
        trsm = blas("trsm", factor, B)
        half = trsm(1.0, factor, B, side=1, lower=0, trans_a=0)          # B U⁻¹
        return trsm(1.0, factor, half, side=1, lower=0, trans_a=1, overwrite_b=True)
    return B @ np.linalg.inv(A)


def pair_distances(points: np.ndarray, seen: np.ndarray, *, spread: bool = True,
                   extent: bool = False) -> tuple:
    """Statistics of the distance between every two markers over the frames seeing both.

    ``points`` is (frames, markers, 3), ``seen`` (frames, markers) bool; unobserved points
    may hold anything. Returns (count, mean, std), each (markers, markers) and symmetric:
    the number of frames where both markers are observed, the mean distance over them and
    its standard deviation (None unless ``spread``); mean and std are 0 where the count
    is 0. With ``extent``, also (lo, hi): the least and largest distance (∞ and −∞ where
    the count is 0). Each pair is computed once (half of a row-by-row loop) from the three
    coordinates held separately, with no (frames × markers × 3) temporaries.
    """
    k = points.shape[1]
    count = np.zeros((k, k), dtype=np.int64)
    tables = [np.zeros((k, k)) for _ in range(1 + spread + 2 * extent)]
    rows = distance_rows(points, seen, [(j, slice(j, None)) for j in range(k)], spread,
                         extent=extent)
    for j, (n_both, *values) in enumerate(rows):
        count[j, j:] = count[j:, j] = n_both
        for table, value in zip(tables, [v for v in values if v is not None]):
            table[j, j:] = table[j:, j] = value
    mean, *rest = tables
    std = rest.pop(0) if spread else None
    return (count, mean, std, *rest)


def distance_rows(points: np.ndarray, seen: np.ndarray, rows: list, spread: bool, *,
                  extent: bool = False):
    """For each (j, others) of ``rows`` (others: a slice or an index array of markers),
    the frames seeing both, mean and std (None unless ``spread``) of the distance from
    marker j to each of ``others``, as :func:`pair_distances` defines them; with
    ``extent``, also its least and largest value over those frames (∞ and −∞ where
    there is none). A generator; the statistics come as float64.

    The distances are taken frame by frame in float32, from coordinates shifted by one
    offset per axis (the mean of the seen samples, the same for every marker, so no
    distance changes and the float32 values stay near the body's own size), one row at a
    time in buffers made once, the markers along the rows. They agree with float64's to
    a few parts in 10⁷ (the least distances, the smallest figures, to 6e−6), and took 11–20
    instead of 31–46 ms for every pair of 85_12's 41 markers over 4,499 frames (mean;
    with the spread; with the extent). The blend makes them up to five times per clip
    (the rigid fill's spreads and PCA's means on both masks, the partner bands).
    """
    n, k, _ = points.shape
    seen_rows = np.ascontiguousarray(seen.T)                      # (markers, frames)
    coords = np.empty((3, k, n), dtype=np.float32)
    for c in range(3):
        x = points[:, :, c].T
        shift = float(x[seen_rows].mean()) if seen_rows.any() else 0.0
        np.copyto(coords[c], np.where(seen_rows, x - shift, 0.0), casting="same_kind")
    squares = np.empty_like(coords)
    both_buffer = np.empty((k, n), dtype=bool)
    spare = np.empty((k, n), dtype=np.float32)
    for j, others in rows:
        q = np.arange(k)[others].size
        both = np.logical_and(seen_rows[others], seen_rows[j], out=both_buffer[:q])
        parts = squares[:, :q]
        np.subtract(coords[:, others], coords[:, j:j + 1], out=parts)
        np.square(parts, out=parts)
        dist = parts[0]
        dist += parts[1]
        dist += parts[2]
        np.sqrt(dist, out=dist)
        n_both = np.count_nonzero(both, axis=1)
        safe = np.maximum(n_both, 1)
        dist *= both
        m = dist.sum(axis=1).astype(np.float64) / safe
        s = None
        t = spare[:q]
        if spread:
            np.subtract(dist, m[:, None].astype(np.float32), out=t)
            t *= both
            np.square(t, out=t)
            s = np.sqrt(t.sum(axis=1).astype(np.float64) / safe)
        if extent:
            t.fill(np.inf)
            np.copyto(t, dist, where=both)
            lo = t.min(axis=1, initial=np.inf).astype(np.float64)
            np.negative(t, out=t)                   # −∞ where unseen
            np.copyto(t, dist, where=both)
            hi = t.max(axis=1, initial=-np.inf).astype(np.float64)
            yield n_both, m, s, lo, hi
        else:
            yield n_both, m, s


def nearest_markers(points: np.ndarray, seen: np.ndarray, count: int) -> np.ndarray:
    """(markers, count): each marker's ``count`` nearest other markers, nearest first, by
    the RMS distance over the frames where both are observed (markers never observed
    together come last). From matrix products (sums of squares and of cross products
    over the frames), not from the distances frame by frame: for 300 markers over 10,000
    frames, 45,000 pairs. ``points`` (frames, markers, 3), ``seen`` (frames, markers)."""
    k = points.shape[1]
    S = seen.astype(np.float64)
    total = np.zeros((k, k))
    for x in _seen_coordinates(points, seen):
        squares = (x * x).T @ S            # Σ x_i² over the frames seeing both i and j
        total += squares + squares.T - 2.0 * (x.T @ x)
    both = S.T @ S
    with np.errstate(divide="ignore", invalid="ignore"):
        rms = np.sqrt(np.maximum(total, 0.0) / both)
    rms[both == 0] = np.inf
    np.fill_diagonal(rms, np.inf)
    return np.argsort(rms, axis=1, kind="stable")[:, :count]


def _seen_coordinates(points: np.ndarray, seen: np.ndarray) -> list[np.ndarray]:
    """The x, y and z of ``points`` (frames, markers, 3), each (frames, markers), 0 where
    not ``seen``."""
    return [np.where(seen, points[:, :, c], 0.0) for c in range(3)]


def simplex_least_squares(gram: np.ndarray, *, max_iter: int | None = None) -> np.ndarray:
    """``argmin wᵀ G w`` over the weights w ≥ 0 with Σw = 1, G symmetric positive
    semi-definite (a Gram matrix of errors), by a primal active-set method.

    From the best single column (the smallest diagonal entry), a column j joins the support
    while (G w)_j < wᵀ G w, the Karush–Kuhn–Tucker condition that fails only where moving
    weight to j lowers the objective; on each support the equality-constrained problem is
    solved exactly (its bordered KKT system), and a step that would make a weight negative
    stops where the first one reaches 0, which leaves the support (Nocedal & Wright,
    *Numerical Optimization*, 2006, §16.5). G is first divided by the best single
    column's error, so the tests compare numbers of order one whatever the candidates'
    scale. The blend used to solve this as non-negative least squares with Σw = 1 as a
    heavily weighted extra row. Where one candidate errs 10⁵ times more than another, that
    row's rounding drowns the others' gradients: a Lawson–Hanson solver written for that
    form stopped on a worse blend in one WalkL_0001 class (residual 1.23e−3 against the
    optimum's 0.96e−3), and scipy's found the optimum only because rounding went its way.
    ``max_iter`` (default 10·k + 10) bounds the support changes; past it the current
    (feasible) weights are returned.

    ``gram`` may also be a stack (P, k, k) of such matrices, solved side by side (weights
    (P, k)): each takes its own steps, and numpy is called once per step for all of
    them. The blend solves thousands of these, three per bootstrap round of each length
    class and long gap (13,244 on a 2,539-frame squat with 147 gaps), each in a few steps
    on k ≈ 8 candidates, so solving them one at a time was all Python overhead: 1.8 s of
    that squat's repair.
    """
    single = np.ndim(gram) == 2
    G = np.array(gram, dtype=np.float64, ndmin=3)            # (P, k, k), a copy
    count, k = G.shape[0], G.shape[1]
    every = np.arange(count)
    diagonal = np.diagonal(G, axis1=1, axis2=2)
    best = diagonal.argmin(axis=1)
    w = np.zeros((count, k))
    w[every, best] = 1.0
    scale = diagonal[every, best].copy()
    # G is divided by the best single column's error; where that error is 0 (or NaN), or
    # ~0 beside others' (the quotient overflows), the best single column is exact.
    active = scale > 0
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        G /= np.where(active, scale, 1.0)[:, None, None]
    active &= np.isfinite(G).all(axis=(1, 2))
    G[~active] = 0.0
    support = w > 0
    blocked = np.zeros((count, k), dtype=bool)   # failed to enter since w last moved
    steps = np.zeros(count, dtype=np.int64)
    limit = 10 * k + 10 if max_iter is None else max_iter
    while True:
        active &= steps < limit
        if not active.any():
            break
        at = np.flatnonzero(active)
        steps[at] += 1
        g = np.einsum("pij,pj->pi", G[at], w[at])
        objective = np.einsum("pi,pi->p", w[at], g)
        free = ~support[at] & ~blocked[at]
        candidate = np.where(free, g, np.inf)
        j = candidate.argmin(axis=1)
        lowest = candidate[np.arange(at.size), j]
        # The KKT condition holds (no column lowers the objective): this one is solved.
        moving = free.any(axis=1) & (lowest < objective * (1.0 - 1e-12))
        active[at[~moving]] = False
        at, j = at[moving], j[moving]
        if at.size == 0:
            break
        trial = support[at]
        trial[np.arange(at.size), j] = True
        z = _simplex_support_solutions(G[at], trial)
        enters = z[np.arange(at.size), j] > 0
        blocked[at[~enters], j[~enters]] = True    # rounding: no descent through j after all
        at, z = at[enters], z[enters]
        support[at] = trial[enters]
        # A step that would make a weight negative stops where the first one reaches 0,
        # which leaves the support; repeated until the support's solution is feasible.
        shrink = (support[at] & (z <= 0)).any(axis=1)
        while shrink.any():
            some = at[shrink]
            ws, zs, held = w[some], z[shrink], support[some]
            shrinking = held & (zs <= 0)
            with np.errstate(divide="ignore", invalid="ignore"):
                ratios = np.where(shrinking, ws / (ws - zs), np.inf)
            first = ratios.argmin(axis=1)
            ws = ws + ratios[np.arange(some.size), first][:, None] * (zs - ws)
            ws[np.arange(some.size), first] = 0.0
            held &= ws > 0
            ws[~held] = 0.0
            w[some], support[some] = ws, held
            z[shrink] = _simplex_support_solutions(G[some], held)
            shrink = (support[at] & (z <= 0)).any(axis=1)
        w[at] = z
        blocked[at] = False
    w /= w.sum(axis=1, keepdims=True)
    return w[0] if single else w


def _simplex_support_solutions(G: np.ndarray, support: np.ndarray) -> np.ndarray:
    """``argmin wᵀ G w`` with Σw = 1 and w = 0 off ``support`` (signs unconstrained), for
    each of G (P, k, k) and support (P, k): the bordered KKT systems [[G_S, 1], [1ᵀ, 0]],
    with the columns off the support decoupled (an identity row and column each) so that
    all have one size and are solved in one call."""
    count, k = support.shape
    on = support.astype(np.float64)
    kkt = np.zeros((count, k + 1, k + 1))
    kkt[:, :k, :k] = G * (on[:, :, None] * on[:, None, :])
    kkt[:, np.arange(k), np.arange(k)] += 1.0 - on
    kkt[:, :k, k] = on
    kkt[:, k, :k] = on
    rhs = np.zeros((count, k + 1, 1))
    rhs[:, k] = 1.0
    try:
        solution = np.linalg.solve(kkt, rhs)
        bad = np.flatnonzero(~np.isfinite(solution).all(axis=(1, 2)))
    except np.linalg.LinAlgError:       # a singular support somewhere: each on its own
        solution, bad = np.empty_like(rhs), np.arange(count)
    for p in bad:
        try:
            solution[p] = np.linalg.solve(kkt[p], rhs[p])
            if np.isfinite(solution[p]).all():
                continue
        except np.linalg.LinAlgError:
            pass
        solution[p] = np.linalg.lstsq(kkt[p], rhs[p], rcond=None)[0]
    return solution[:, :k, 0] * on
