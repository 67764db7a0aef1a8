"""PCA gap filling from marker intercorrelations (Gløersen & Federolf 2016).

Gløersen Ø. & Federolf P. (2016), "Predicting missing marker trajectories in human motion
data using marker intercorrelations", PLoS ONE 11(3): e0152616 — the MATLAB function
PredictMissingMarkers of its supporting information, reconstruction strategy R2 (its
default), which builds on Federolf (2013), PLoS ONE 8(10): e78689. Written from the paper's
description; no code copied.

For each marker i with gaps (time as rows, coordinates as columns, as in the paper):

1. The mean trajectory of the markers without gaps is subtracted from every marker (a
   coordinate system moving with the subject).
2. Predictor markers: every other marker that is observed throughout i's gaps, except
   gapped markers farther from i than ``distal_threshold`` × (mean distance from i to all
   markers). Distances are Euclidean, averaged over the frames where both are observed.
3. Training frames: frames where i and all predictors are observed. On them, each column
   is mean-centred and divided by its standard deviation, then multiplied by its marker's
   weight ``w_j = exp(−d_ij² / (2σ²))``; marker i itself gets ``mm_weight`` (0.02).
4. PCA of this matrix N and of N₀ (the same with i's columns zeroed); the number of PCs is
   the smallest k whose cumulative sum of singular values reaches ``min_cum_sv`` (0.99) of
   the total, the larger k of the two.
5. A gapped frame, normalised the same way with i's columns zero (m₀), is mapped into the
   PC basis of N₀, transformed to the basis of N and back to coordinates:
   ``x̂ = m₀ V₀ B Vᵀ``, de-normalised; i's coordinates are the prediction.
   For B the published code uses ``Vᵀ V₀`` (``transform="published"``, the default).
   ``transform="inverse"`` uses ``(Vᵀ V₀)⁺`` instead, which makes the prediction exact
   when the data are exactly low-rank (the published matrix is off by a few per cent
   there), but amplifies noise where Vᵀ V₀ is ill-conditioned: on the walking sample clip
   (6 markers × 1 s gaps) it gave a 0.24 relative gap error against 0.04 for the published
   transform, which is therefore kept as the default.

Units. The published weight scale σ = 200 mm is absolute; the pipeline hands methods
unit-free data (rows centred, unit RMS), so σ is relative here: σ = ``weight_scale`` ×
(mean distance from marker i to all markers), default 0.3 — roughly 200 mm on a full-body
marker set, whose markers lie some 0.6–0.7 m from each other on average.

No complete frame (our fallback, in the spirit of the later versions of the function,
which use whatever frames and markers are available): when the predictors of step 2 leave
fewer than ``min_frames`` training frames, the gapped predictor missing most often in i's
observed frames is dropped, repeatedly; if no predictor is left, the gap frames are split
into groups sharing the same set of available markers and each group is filled on its own
(predictors: the markers available in it, the distal rule relaxed if necessary). Frames
where no marker at all can serve as predictor are filled by linear interpolation of i
along time (ends held). A marker never observed is filled with 0.

Observed samples are returned unchanged.
"""
from __future__ import annotations

import numpy as np

from ..gaps import missing_runs
from ._linalg import as_problem, distance_rows, linear_fill

__all__ = ["complete", "gap_fill"]


def _marker_mask(observed: np.ndarray) -> np.ndarray:
    """(markers, frames) bool: all three coordinates observed."""
    m, n = observed.shape
    return observed.reshape(m // 3, 3, n).all(axis=1)


def _distances(P: np.ndarray, mask: np.ndarray, markers: list[int]) -> np.ndarray:
    """Mean Euclidean distance from each of ``markers`` to every marker over the frames
    where both are observed, (len(markers), all markers).

    ``P`` is (markers, 3, frames) with missing samples arbitrary; ``inf`` where two markers
    are never observed together. Only the gapped markers' distances are read: on 85_12
    with ten of its 41 markers gapped, 410 pairs instead of all 861.
    """
    rows = distance_rows(P.transpose(2, 0, 1), mask.T,
                         [(j, slice(None)) for j in markers], spread=False)
    return np.array([np.where(count > 0, mean, np.inf) for count, mean, _ in rows]
                    ).reshape(len(markers), mask.shape[0])


def _n_components(s: np.ndarray, min_cum_sv: float) -> int:
    total = s.sum()
    if total <= 0:
        return 1
    return int(np.searchsorted(np.cumsum(s), min_cum_sv * total * (1 - 1e-12)) + 1)


def _right_singular(gram: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Singular values and right singular vectors (rows of Vᵀ) of a tall A, descending,
    from its small Gram matrix ``gram`` = AᵀA.

    The same subspaces as the SVD of A at a fraction of its cost for frames ≫ columns
    (4499 × 123: 3 ms against 50 ms). Eigenvalues within rounding of zero (below 1e−12 of
    the largest: singular values under 1e−6 of the largest, which the Gram matrix cannot
    resolve) are read as 0, so an exactly low-rank A keeps its rank.
    """
    values, vectors = np.linalg.eigh(gram)
    order = np.argsort(values)[::-1]
    values = values[order]
    values[values < 1e-12 * max(values[0], 0.0)] = 0.0
    return np.sqrt(values), vectors[:, order].T


# Models of up to this many columns take their axes from the Gram matrix whatever their
# training frames: 3 × 41, the most a model has on the accuracy tables' clips (CMU: 41
# markers, the walking set: 37), where a Gram matrix's eigendecomposition costs about a
# millisecond and the fills stay bit for bit. Wider models with more than twice as many
# columns as training frames take them from the training matrix's thin SVD
# (:func:`_axes_wide`), which is then the cheaper (1,003 columns on one thread: the
# eigendecomposition 0.08–0.13 s whatever the frames; the SVD 0.005 s on 100 frames,
# 0.07 on 500, 0.27 on 1,000).
GRAM_COLUMNS = 123


def _right_singular_wide(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_right_singular` of AᵀA for a wide A (rows < columns), from A's thin SVD:
    min(rows, columns) values, the rest being 0, with the same cut (singular values under
    1e−6 of the largest read as 0)."""
    _, s, Vt = np.linalg.svd(A, full_matrices=False)
    s[s < 1e-6 * max(s[0], 0.0)] = 0.0
    return s, Vt


class _Moments:
    """The sums behind every model's Gram matrix over the clip's complete frames, once.

    A model's training frames are the frames where its marker and its predictors are
    seen: on most clips the complete frames and a few more. Its cross-product is the
    complete frames' (restricted to its columns) plus that of the few others, so a model
    costs a product over those few frames instead of a copy and a product over all of
    them. On 85_12 with ten 40-frame gaps (4,099 complete frames of 4,499): 9.7 → 3.1 ms
    per model (profiled), the default's PCA candidate 0.136 → 0.086 s (medians of 7 × 3
    runs). The sums are taken about the complete frames' mean; the fills move by rounding
    only (the accuracy benchmark's records by 0.0013 mm at most, its means not at all).
    """

    def __init__(self, X: np.ndarray, complete: np.ndarray):
        self.complete = complete                       # (n,) bool
        Z = X[complete]
        self.shift = Z.mean(axis=0)
        Z -= self.shift
        self.sum = Z.sum(axis=0)
        self.scatter = Z.T @ Z

    def centred(self, X: np.ndarray, train: np.ndarray, cols: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray] | None:
        """The centred cross-product and the mean of X[train, cols], or None where the
        complete frames are not most of ``train``."""
        extra = train[~self.complete[train]]
        if 2 * len(extra) > len(train):
            return None
        shift = self.shift[cols]
        Z = X[np.ix_(extra, cols)] - shift
        offset = (self.sum[cols] + Z.sum(axis=0)) / len(train)
        scatter = self.scatter[np.ix_(cols, cols)] + Z.T @ Z
        return scatter - len(train) * np.outer(offset, offset), shift + offset


def _model(X: np.ndarray, i: int, predictors: list[int], train: np.ndarray,
           weights: np.ndarray, min_cum_sv: float, transform: str,
           moments: _Moments | None = None) -> tuple:
    """Fit the reconstruction of marker i from ``predictors`` on the ``train`` frames.

    Returns what :func:`_predict` needs: the columns, the normalisation of N₀ and the
    (columns × 3) map ``V₀ B Vᵀ`` restricted to i's coordinates.
    """
    cols = np.concatenate([np.arange(3 * j, 3 * j + 3) for j in predictors + [i]])
    w = np.repeat(weights, 3)
    wide = len(cols) > max(2 * len(train), GRAM_COLUMNS)
    if wide:
        mean_N, std, (s, Vt), (s0, V0t) = _axes_wide(X, cols, train, w)
    else:
        mean_N, std, (s, Vt), (s0, V0t) = _axes_gram(X, cols, train, w, moments)
    mean_N0 = mean_N.copy()
    mean_N0[-3:] = 0.0
    k = max(_n_components(s, min_cum_sv), _n_components(s0, min_cum_sv))
    k = min(k, Vt.shape[0], V0t.shape[0])
    V = Vt[:k].T
    V0 = V0t[:k].T
    B = V.T @ V0
    if transform == "inverse":
        B = np.linalg.pinv(B)
    # Only the gapped marker's columns are wanted (a far predictor's weight may be 0); a
    # wide model forms only those (its whole map would be columns² × PCs).
    transfer = V0 @ B @ V[-3:].T if wide else (V0 @ B @ V.T)[:, -3:]
    return cols, mean_N0, std, w, transfer, mean_N[-3:]


def _axes_gram(X: np.ndarray, cols: np.ndarray, train: np.ndarray, w: np.ndarray,
               moments: _Moments | None) -> tuple:
    """The mean and standard deviation of N = X[train, cols], and the singular values and
    right singular vectors of N and N₀ normalised, from their Gram matrices."""
    known = None if moments is None else moments.centred(X, train, cols)
    if known is not None:
        centred, mean_N = known
    else:
        # The normalised matrix (N − mean)/std·w is never formed: its Gram matrix is the
        # centred cross-product of N scaled on both sides, from one product and one sum
        # (on a 12,000-frame window the passes over N were most of a model's cost).
        N, origin, offset = _shifted(X, train, cols)
        centred = N.T @ N - len(train) * np.outer(offset, offset)
        mean_N = origin + offset
    std = np.sqrt(np.maximum(np.diag(centred), 0.0) / len(train))
    std[std == 0] = 1.0
    scale = w / std
    # N₀ is N with i's columns zeroed: after the same normalisation its Gram matrix is
    # N's with those rows and columns zeroed, so one product serves both PCAs.
    gram = centred * np.outer(scale, scale) / max(len(train) - 1, 1)
    gram0 = gram.copy()
    gram0[-3:, :] = 0.0
    gram0[:, -3:] = 0.0
    return mean_N, std, _right_singular(gram), _right_singular(gram0)


def _shifted(X: np.ndarray, train: np.ndarray, cols: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """N = X[train, cols] less its first row (so that a constant column gives exactly 0),
    that row, and the mean of the shifted N."""
    N = X[np.ix_(train, cols)]
    origin = N[0].copy()
    N -= origin
    return N, origin, N.sum(axis=0) / len(train)


def _axes_wide(X: np.ndarray, cols: np.ndarray, train: np.ndarray, w: np.ndarray
               ) -> tuple:
    """:func:`_axes_gram` for a model with more than twice as many columns as training
    frames, and more than :data:`GRAM_COLUMNS`: many markers over few frames.

    The Gram matrices there are columns × columns of rank below the frames: 1,000
    markers over 30 frames made two 3,003 × 3,003 eigendecompositions per model, 1 s
    each. The normalised N itself (frames × columns) has the same singular values and
    right singular vectors, from a thin SVD costing frames² × columns, and N₀ is N with
    the marker's columns zeroed. The axes' signs are LAPACK's choice either way, which
    the published transform Vᵀ V₀ cancels only nearly (where V₀ ≈ V, as the marker's
    small weight makes them): the fills move by rounding-sized amounts (1,000 markers
    over 30 and over 100 frames: by 4e−5 and 4e−4 mm at most, the errors the same to
    1e−6 mm).
    """
    N, origin, offset = _shifted(X, train, cols)
    N -= offset
    std = np.sqrt((N * N).sum(axis=0) / len(train))
    std[std == 0] = 1.0
    N *= w / std / np.sqrt(max(len(train) - 1, 1))
    axes = _right_singular_wide(N)
    N[:, -3:] = 0.0
    return origin + offset, std, axes, _right_singular_wide(N)


def _predict(X: np.ndarray, model: tuple, frames: np.ndarray) -> np.ndarray:
    """Marker i on ``frames`` from the predictors' coordinates there (frames × 3)."""
    cols, mean_N0, std, w, transfer, mean_i = model
    M0 = X[np.ix_(frames, cols)]
    M0[:, -3:] = 0.0
    M0n = (M0 - mean_N0) / std * w
    return mean_i + (M0n @ transfer) * std[-3:] / w[-3:]


def _bit_rows(visible: np.ndarray) -> np.ndarray:
    """(frames, w) uint64: each column of ``visible`` (markers × frames, bool) packed into
    big-endian words, first marker in the highest bit, so that the words of two columns
    compare as the columns do lexicographically."""
    packed = np.packbits(visible, axis=0)                            # (bytes, frames)
    padding = -packed.shape[0] % 8
    if padding:
        packed = np.concatenate([packed, np.zeros((padding, packed.shape[1]), np.uint8)])
    return np.ascontiguousarray(packed.T).view(">u8").astype(np.uint64)


def _patterns(visible: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct columns of ``visible`` (markers × frames, bool) as rows, in the
    lexicographic order of ``np.unique(visible.T, axis=0)``, and the row of each frame.

    The columns are packed into words first (on a 12,000-frame window, sorting boolean
    rows as ``np.unique(axis=0)`` does took 7 ms per marker).
    """
    words = _bit_rows(visible)
    if words.shape[1] == 1:
        _, first, groups = np.unique(words[:, 0], return_index=True, return_inverse=True)
    else:
        _, first, groups = np.unique(words, axis=0, return_index=True, return_inverse=True)
    return visible[:, first].T, np.asarray(groups).ravel()


def _fill_marker(X: np.ndarray, mask: np.ndarray, i: int, weights: np.ndarray,
                 distal: np.ndarray, complete_markers: np.ndarray, backup_i: np.ndarray, *,
                 min_frames: int, mm_weight: float, min_cum_sv: float,
                 transform: str, words: np.ndarray, bits: np.ndarray,
                 max_models: int | None = None, edges: bool = False,
                 end_edges: tuple[bool, bool] = (False, False),
                 moments: _Moments | None = None) -> np.ndarray:
    """Predictions of marker i on its gap frames, (frames, 3), NaN elsewhere. ``words`` is
    ``_bit_rows(mask)``, every frame's visible markers, and ``bits`` each marker's bit
    (both the same for every marker of the clip).

    With ``edges``, also the prediction on the observed frame just before and just after
    each interior gap, by the model that filled the gap's frame beside it, where that
    model's predictors are observed there (NaN elsewhere, and beside frames filled by the
    linear backup, which meets the data already): :func:`gap_fill` joins the fill to the
    data with the offsets there. With ``end_edges`` (start, end) too, the prediction on
    the observed frame beside each end gap that :func:`gap_fill` joins there
    (:func:`_joined_end`). The gap frames' predictions are the same either way."""
    k, n = mask.shape
    others = np.array([j for j in range(k) if j != i], dtype=int)
    mask_others = mask[others]
    obs_i = mask[i]
    fill = np.full((n, 3), np.nan)
    # Frame groups that end with the same predictors share one model (the training frames
    # depend on the predictors only): on clips with many overlapping gaps this turns
    # thousands of PCAs into tens.
    models: dict[tuple[int, ...], tuple] = {}
    # Where the fallback that drops gapped predictors ends, from each starting set (it
    # depends on that set only; thousands of frame groups share a few starting sets).
    reached: dict[bytes, tuple[tuple[int, ...], np.ndarray] | None] = {}

    # Frames where i is observed and marker j is not: what keeping j as a predictor costs
    # in training frames (the fallback drops the gapped predictor that costs most).
    cost = (~mask & obs_i).sum(axis=1)
    # "i and every predictor observed" is one pass over the n words of the frames' visible
    # markers, not a (predictors × n) copy: thousands of starting sets are tried.

    def fallback(usable: np.ndarray) -> tuple[tuple[int, ...], np.ndarray] | None:
        """From the ``usable`` other markers, the predictors with enough training frames,
        and those frames; None if none."""
        start = usable.tobytes()            # the memo's key: cheaper than a tuple of ints
        if start not in reached:
            preds, found = others[usable].tolist(), None
            while preds:
                wanted = np.bitwise_or.reduce(bits[preds], axis=0)
                train = obs_i & ((words & wanted) == wanted).all(axis=1)
                if train.sum() >= min_frames:
                    if np.any(weights[preds] != 0):
                        found = (tuple(preds), train)
                    break
                gappy = [j for j in preds if not complete_markers[j]]
                if not gappy:
                    break
                # drop the gapped predictor that costs most training frames (the first)
                preds.remove(max(gappy, key=cost.__getitem__))
            reached[start] = found
        return reached[start]

    # Frames to fill: (frames, the other markers visible on all of them, relax, split),
    # taken depth first (the model budget goes to the groups in this order). A group
    # without a model is split by the other markers' visibility, then tried with the
    # distal markers allowed (relax), then takes the backup. (A loop, not a recursive
    # closure: that closure's reference cycle kept each marker's models and masks alive
    # until the next garbage collection; on the 216,000-frame clip the peak went 1.44 →
    # 2.19 GB once the search memo made that garbage larger.)
    gap = np.flatnonzero(~obs_i)
    # The model that filled each frame (its index in ``models``, −1: the backup), for the
    # predictions beside the gaps (``edges``).
    filled_by = np.full(n, -1)
    todo = [(gap, mask_others[:, gap].all(axis=1), False, True)]
    allowed = complete_markers[others] | ~distal[others]       # without relaxing
    while todo:
        frames, avail, relax, split = todo.pop()
        found = fallback(avail if relax else avail & allowed)
        if found is not None:
            key, train = found
            if key in models or max_models is None or len(models) < max_models:
                if key not in models:
                    w = np.append(weights[list(key)], mm_weight)
                    models[key] = _model(X, i, list(key), np.flatnonzero(train), w,
                                         min_cum_sv, transform, moments)
                fill[frames] = _predict(X, models[key], frames)
                if edges:
                    filled_by[frames] = list(models).index(key)
                continue
            # budget spent: these frames take the split, then the backup
        if split:
            # Within a group the other markers' visibility is one pattern: its avail.
            patterns, groups = _patterns(mask_others[:, frames])
            if len(patterns) > 1:
                todo.extend((frames[groups == g], patterns[g], False, False)
                            for g in reversed(range(len(patterns))))
                continue
        if not relax:
            todo.append((frames, avail, True, False))
            continue
        fill[frames] = backup_i[:, frames].T
    if edges:
        runs = np.array([(a, b) for a, b in missing_runs(obs_i)
                         if (0 < a and b < n) or _joined_end(a, b, n, end_edges)],
                        dtype=np.int64).reshape(-1, 2)
        left, right = runs[runs[:, 0] > 0], runs[runs[:, 1] < n]   # (a seen frame beside)
        edge = np.concatenate([left[:, 0] - 1, right[:, 1]])
        model = filled_by[np.concatenate([left[:, 0], right[:, 1] - 1])]
        # One prediction per model, of the edges where its predictors are all observed.
        for index, key in enumerate(models):
            frames = edge[model == index]
            frames = frames[mask[list(key)][:, frames].all(axis=0)]
            if frames.size:
                fill[frames] = _predict(X, models[key], frames)
    return fill


def complete(matrix: np.ndarray, observed: np.ndarray, *, weight_scale: float = 0.3,
             mm_weight: float = 0.02, distal_threshold: float = 0.5,
             min_cum_sv: float = 0.99, min_frames: int = 10,
             subtract_mean_trajectory: bool = True, transform: str = "published",
             max_models: int | None = None, rate: float | None = None,
             seed: int | None = None, centre: np.ndarray | None = None) -> np.ndarray:
    """Fill gaps by Gløersen & Federolf's (2016) weighted-PCA method, strategy R2.

    Parameters
    ----------
    weight_scale
        σ of the distance weights relative to the mean distance from the gapped marker to
        all markers (the paper's absolute 200 mm; see the module notes).
    mm_weight
        Weight of the gapped marker's own columns (paper: 0.02).
    distal_threshold
        Gapped markers farther than this × the mean distance are not used (paper: 0.5).
    min_cum_sv
        Fraction of the summed singular values the retained PCs must reach (paper: 0.99).
    min_frames
        Fewest training frames before the fallback drops predictors (ours).
    subtract_mean_trajectory
        Step 1 (paper: yes); skipped automatically when no marker is gap-free.
    transform
        "published" (default, ``Vᵀ V₀``) or "inverse" (``(Vᵀ V₀)⁺``, exact on exactly
        low-rank data, fragile on noisy data).
    rate, seed
        Shared pipeline options, ignored.
    max_models
        Most distinct predictor sets (PCA models) per gapped marker; frames beyond the
        budget are filled by linear interpolation (ours; default unlimited). Clips whose
        gaps overlap in many different combinations otherwise cost one PCA per
        combination (a synthetic 6000-frame clip with 5 % gaps on every marker: 732 PCAs,
        7 s); the default method's blend uses 8 per marker.
    centre
        (rows,) where each row's zero lies in true coordinates, for a matrix whose rows
        were centred one by one (the pipeline passes its unit scale's centres): the
        distances behind the weights and the distal rule are the markers' true ones.
        Centring each coordinate on its own mean moves every marker by its own mean
        position, and the distances between those deviations weighted the predictors
        before (mean over WalkL_0001–0010: 3.51 mm so, 2.85 mm with true distances;
        the rest of the method does not depend on the rows' offsets).
    """
    return _complete(matrix, observed, weight_scale=weight_scale, mm_weight=mm_weight,
                     distal_threshold=distal_threshold, min_cum_sv=min_cum_sv,
                     min_frames=min_frames, subtract_mean_trajectory=subtract_mean_trajectory,
                     transform=transform, max_models=max_models, join=False, centre=centre)


def _joined_end(a: int, b: int, n: int, sides: tuple[bool, bool]) -> bool:
    """Whether :func:`gap_fill` joins the gap [a, b) of an n-frame clip as an end gap: one
    touching an end named in ``sides`` (start, end), of ``MIN_MODEL_GAP`` frames or more."""
    from .gapwise import MIN_MODEL_GAP

    return (a == 0) != (b == n) and sides[a != 0] and b - a >= MIN_MODEL_GAP


def gap_fill(matrix: np.ndarray, observed: np.ndarray, *,
             ends: bool | tuple[bool, bool] = True, **options) -> np.ndarray:
    """The PCA fill as a candidate of the per-gap blend (:mod:`.gapwise`): :func:`complete`
    with every interior gap joined to the samples just outside it (and, with ``ends``,
    every end gap of ``MIN_MODEL_GAP`` frames or more to the sample beside it).

    The prediction of a gap reads the predictors only, so at the gap's first and last
    frames it is off the marker's own samples beside it by the model's error there (on
    real clips a median 9.5 mm, one gap in ten over 50 mm, up to 430), and a blend giving
    it weight stepped into and out of the gap. As for the TrNN, regression and Gaussian
    candidates, the offsets between the data and the model's prediction on the observed
    frames beside the gap are added along the gap as a linear ramp (where the model
    cannot predict there, that side's offset is 0).

    An end gap (filled where ``--ends extrapolate`` asks) has one such side: its offset
    there is added all along the gap. Measured (``scripts/end_gaps.py sums``, thirty-
    seventh session; summed end-gap errors of the default, mm): on end gaps of 5 frames or
    more, held-out seeds 9–11 of the seven cases 78.51 → 76.25, seeds 4–6 of the extra set
    37.42 → 36.43; seeds 3–5 and 6–8 65.39 → 61.58 and 76.63 → 73.13, seeds 1–3 of the
    extra set 31.85 → 32.29. On every end gap, the random loss's 1–4-frame ones lost
    (49.97 → 51.13); an offset fading over 10 or 100 frames did worse than a constant one.
    Without ``ends`` (where the end fills are not used) end gaps are not joined: the
    windows of a long clip may fill their inner edges' gaps with this candidate's fill.
    ``ends`` may name one end, as a (start, end) pair
    (:func:`~mocapfill.solvers.gapwise.end_sides`: a window holding one of the clip's
    ends).
    """
    from .gapwise import end_sides

    matrix, observed = as_problem(matrix, observed)
    return _complete(matrix, observed, **options, join=True, join_ends=end_sides(ends))


def _complete(matrix: np.ndarray, observed: np.ndarray, *, weight_scale: float = 0.3,
              mm_weight: float = 0.02, distal_threshold: float = 0.5,
              min_cum_sv: float = 0.99, min_frames: int = 10,
              subtract_mean_trajectory: bool = True, transform: str = "published",
              max_models: int | None = None, join: bool = False,
              join_ends: tuple[bool, bool] = (False, False),
              centre: np.ndarray | None = None) -> np.ndarray:
    matrix, observed = as_problem(matrix, observed)
    m, n = matrix.shape
    if m % 3:
        raise ValueError(f"rows must be x, y, z of each marker (m divisible by 3), got m={m}")
    if transform not in ("inverse", "published"):
        raise ValueError(f"transform must be 'inverse' or 'published', got {transform!r}")
    if not 0 < min_cum_sv <= 1 or mm_weight <= 0 or weight_scale <= 0:
        raise ValueError("need 0 < min_cum_sv <= 1, mm_weight > 0, weight_scale > 0")

    mask = _marker_mask(observed)  # (k, n)
    k = m // 3
    obs3 = np.repeat(mask, 3, axis=0)
    out = np.where(observed, matrix, 0.0)
    gapped = [i for i in range(k) if not mask[i].all()]
    if not gapped:
        return out

    P = np.where(obs3, matrix, 0.0).reshape(k, 3, n)
    complete_markers = mask.all(axis=1)
    mean_traj = np.zeros((3, n))
    if subtract_mean_trajectory and complete_markers.any():
        mean_traj = P[complete_markers].mean(axis=0)
    P = P - mean_traj[None]
    X = P.reshape(m, n).T.copy()  # frames × coordinates, the paper's layout
    X[~obs3.T] = np.nan
    true = P if centre is None else P + np.asarray(centre, dtype=np.float64).reshape(k, 3, 1)
    dist = dict(zip(gapped, _distances(true, mask, gapped)))
    # The last resort, on the gapped markers' rows only.
    rows3 = np.concatenate([np.arange(3 * i, 3 * i + 3) for i in gapped])
    backup = dict(zip(gapped, linear_fill(np.where(obs3[rows3], P.reshape(m, n)[rows3], 0.0),
                                         obs3[rows3]).reshape(len(gapped), 3, n)))

    # Every frame's visible markers as bits (n, w), and each marker's bit, for the searches.
    words, bits = _bit_rows(mask), _bit_rows(np.eye(k, dtype=bool))
    complete_frames = mask.all(axis=0)
    moments = _Moments(X, complete_frames) if complete_frames.sum() >= min_frames else None
    for i in gapped:
        if not mask[i].any():
            continue  # never observed: stays 0
        d = dist[i].copy()
        d[i] = 0.0
        finite = np.isfinite(d)
        mean_d = d[finite].mean()
        sigma = weight_scale * mean_d if mean_d > 0 else 1.0
        weights_all = np.where(finite, np.exp(-np.where(finite, d, 0.0) ** 2
                                               / (2.0 * sigma ** 2)), 0.0)
        distal = ~finite | (d > distal_threshold * mean_d)
        fill = _fill_marker(X, mask, i, weights_all, distal, complete_markers,
                            backup[i], min_frames=min_frames,
                            max_models=max_models, words=words, bits=bits,
                            mm_weight=mm_weight, min_cum_sv=min_cum_sv, transform=transform,
                            edges=join, end_edges=join_ends, moments=moments)
        gap = ~mask[i]
        rows = slice(3 * i, 3 * i + 3)
        values = fill.T + mean_traj
        if join:
            from .gapwise import ramp

            # The ramp of the offsets (data − prediction) beside each interior gap, 0
            # where there is no prediction.
            offset = np.nan_to_num(np.where(obs3[rows], matrix[rows], np.nan) - values)
            for a, b in missing_runs(mask[i]):
                if a > 0 and b < n:
                    values[:, a:b] += ramp(offset[:, a - 1], offset[:, b], b - a)
                elif _joined_end(a, b, n, join_ends):
                    values[:, a:b] += offset[:, a - 1 if a > 0 else b][:, None]
        out[rows, gap] = np.where(observed[rows, gap], out[rows, gap], values[:, gap])
    return out


complete.takes_centre = True        # the pipeline passes its rows' centres (see above)
