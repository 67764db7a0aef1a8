"""Gaps: finding them, describing them, and simulating them with the paper's protocols."""
from __future__ import annotations

from dataclasses import dataclass
from numbers import Real

import numpy as np

from .errors import NothingToRepair, ParameterError, named
from .motion import Motion, require_motion, whole_number


@dataclass(frozen=True)
class Gap:
    """One run of consecutive missing frames of one marker; ``stop`` is exclusive."""

    marker: int
    label: str
    start: int
    stop: int
    n_frames_clip: int

    @property
    def length(self) -> int:
        return self.stop - self.start

    @property
    def at_start(self) -> bool:
        return self.start == 0

    @property
    def at_end(self) -> bool:
        return self.stop == self.n_frames_clip

    @property
    def whole_clip(self) -> bool:
        return self.at_start and self.at_end


def missing_runs(observed: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) of every run of False in a 1-D observed mask."""
    missing = np.concatenate(([False], ~np.asarray(observed, bool), [False]))
    edges = np.flatnonzero(missing[1:] != missing[:-1])
    return list(zip(edges[0::2].tolist(), edges[1::2].tolist()))


def gap_frames(starts: np.ndarray, stops: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For runs [starts[i], stops[i]): every frame of every run and the run it is in,
    run after run (vectorised form of a loop over ``range(a, b)`` per run)."""
    lengths = stops - starts
    run = np.repeat(np.arange(lengths.size), lengths)
    position = np.arange(lengths.sum()) - np.repeat(np.cumsum(lengths) - lengths, lengths)
    return run, starts[run] + position


def find_gaps(motion: Motion) -> list[Gap]:
    """Every gap of every marker, in marker order then time order."""
    return [Gap(j, motion.labels[j], start, stop, motion.n_frames)
            for j in range(motion.n_markers)
            for start, stop in missing_runs(motion.observed[:, j])]


@dataclass(frozen=True)
class MarkerSummary:
    """Missing-data summary of one marker: "LASI: 120/4300 (2.8%), 3 gaps, longest 80"."""

    label: str
    missing: int
    frames: int
    gaps: int
    longest: int
    rate: float

    @property
    def percent(self) -> float:
        return 100.0 * self.missing / self.frames if self.frames else 0.0

    @property
    def longest_s(self) -> float:
        return self.longest / self.rate if self.rate > 0 else float("nan")


def summarise(motion: Motion) -> list[MarkerSummary]:
    """Per-marker missing count, number of gaps and longest gap."""
    rows = []
    for j, label in enumerate(motion.labels):
        runs = missing_runs(motion.observed[:, j])
        rows.append(MarkerSummary(label, int((~motion.observed[:, j]).sum()), motion.n_frames,
                                  len(runs), max((b - a for a, b in runs), default=0),
                                  motion.rate))
    return rows


def simulate_gaps(motion: Motion, *, mr: float | None = None, ml: int | None = None,
                  markers: int | None = None, seed: int | None = None) -> Motion:
    """Remove samples with one of the paper's two protocols, on top of existing gaps.

    Parameters
    ----------
    mr
        "Random missing": in every frame a fraction ``mr`` of the candidate markers
        (rounded) is removed, chosen at random among those observed in that frame, and
        never all of these.
    ml
        "Continuous missing": ``markers`` random markers each lose ``ml`` consecutive
        observed frames: a new interior gap of exactly ``ml`` frames, seen just before and
        after, so it never touches the clip's ends (end gaps are left unfilled by default
        and would not be scored) nor joins a gap the clip had. Only markers with such a
        stretch (``ml`` + 2 frames observed in a row) are hit: see
        :func:`simulation_candidates`.
    markers
        Number of markers hit by the continuous protocol (default 10); not with ``mr``.
    seed
        Seed of the random generator; the same seed gives the same gaps (and, on a clip
        without gaps, the same ones as before the rules above took the clip's own gaps
        into account: those draws are made first, unchanged, and only a run that would
        meet a gap is drawn again).

    ``ml``, ``markers`` and ``seed`` are whole numbers (numpy's integers and whole floats
    such as 40.0 are taken as the int), ``mr`` a number; anything else, or a count out of
    its range, is a ParameterError, as on the command line.

    Only fillable markers with at least one observed sample are candidates, and a
    marker never loses its last observed sample.
    """
    require_motion(motion, "simulate_gaps")
    if (mr is None) == (ml is None):
        raise ParameterError("give exactly one of mr (random missing) or ml (continuous missing)")
    # The command line's rules, checked before anything is drawn: ml=3.0 failed deep
    # inside (slice indices must be integers), ml=True acted as 1, and markers given with
    # mr was ignored (the command line refuses --markers with --mr).
    if markers is not None and mr is not None:
        raise ParameterError("markers applies to ml (continuous missing), not mr")
    if mr is not None and (isinstance(mr, (bool, np.bool_)) or not isinstance(mr, Real)):
        raise ParameterError(f"mr must be a number in [0, 1), got {mr!r}")
    for name, value in (("ml", ml), ("markers", markers), ("seed", seed)):
        if value is not None and not whole_number(value):
            raise ParameterError(f"{name} must be a whole number, got {value!r}")
    ml = None if ml is None else int(ml)
    markers = 10 if markers is None else int(markers)
    seed = None if seed is None else int(seed)
    if seed is not None and seed < 0:
        raise ParameterError(f"seed must be ≥ 0, got {seed}")
    rng = np.random.default_rng(seed)
    observed = motion.observed.copy()
    candidates = simulation_candidates(motion)
    if candidates.size == 0:
        raise NothingToRepair(f"{named(motion.path)}no marker with observed samples to remove")
    n_frames = motion.n_frames
    if mr is not None:
        if not 0 <= mr < 1:
            raise ParameterError(f"mr must be in [0, 1), got {mr}")
        # Never every marker of a frame: mr < 1, and with all of them gone (mr ≥ 1 − 0.5/n
        # rounds up to n) the clip kept only the first sample of each marker.
        k = min(int(round(mr * candidates.size)), candidates.size - 1)
        if k:
            # argsort of uniform noise: an independent random k-subset in every frame, of
            # the markers seen there (the missing ones sort last: a pick among them removed
            # nothing, and on a clip with gaps fewer samples went than asked), and never
            # all of those.
            seen = observed[:, candidates]
            noise = np.where(seen, rng.random((n_frames, candidates.size)), 2.0)
            order = np.argsort(noise, axis=1)[:, :k]
            take = np.minimum(k, np.maximum(seen.sum(axis=1) - 1, 0))
            hit = np.zeros((n_frames, candidates.size), bool)
            np.put_along_axis(hit, order, np.arange(k) < take[:, None], axis=1)
            observed[:, candidates] &= ~hit
    else:
        if ml < 1:
            raise ParameterError(f"ml must be a positive number of frames, got {ml}")
        if ml > n_frames - 2:
            raise ParameterError(f"ml = {ml} frames does not fit inside a {n_frames}-frame clip")
        if markers < 1:
            raise ParameterError(f"markers must be positive, got {markers}")
        chosen = rng.choice(candidates, size=min(markers, candidates.size), replace=False)
        starts = [int(rng.integers(1, n_frames - ml)) for _ in chosen]
        _place_runs(observed, candidates, chosen.tolist(), starts, ml,
                    min(markers, candidates.size), np.random.default_rng(rng.integers(2**63)))
    # Keep at least one observed sample per marker that had one.
    lost = motion.observed.any(axis=0) & ~observed.any(axis=0)
    for j in np.flatnonzero(lost):
        first = int(np.flatnonzero(motion.observed[:, j])[0])
        observed[first, j] = True
    return motion.with_positions(motion.positions, observed)


def _place_runs(observed: np.ndarray, candidates: np.ndarray, chosen: list[int],
                starts: list[int], ml: int, wanted: int, again: np.random.Generator) -> None:
    """Hide ``ml`` frames of each ``chosen`` marker from its drawn start (in place), where
    that run and the frames just before and after it are observed; otherwise at a start
    drawn ``again`` among those where they are, and a marker with none gives its place to
    another candidate that has one, until ``wanted`` markers are hit or none is left.

    The first draws are the protocol's as they always were: on a clip without gaps they
    all stand, and the fill benchmarks' gaps do not move.
    """
    taken = set(chosen)
    spare = [j for j in again.permutation(candidates).tolist() if j not in taken]
    hit = 0
    for j, start in [*zip(chosen, starts), *((j, None) for j in spare)]:
        if hit >= wanted:
            break
        if start is None or not observed[start - 1:start + ml + 1, j].all():
            options = _run_starts(observed[:, j], ml)
            if not options.size:
                continue
            start = int(again.choice(options))
        observed[start:start + ml, j] = False
        hit += 1


def _run_starts(seen: np.ndarray, ml: int) -> np.ndarray:
    """The frames s where a run of ``ml`` frames may start in a marker's mask ``seen``:
    s − 1 … s + ml all observed (ml + 2 in a row)."""
    run = np.convolve(seen.astype(np.int64), np.ones(ml + 2, np.int64), "valid")
    return np.flatnonzero(run == ml + 2) + 1


def simulation_candidates(motion: Motion, ml: int | None = None) -> np.ndarray:
    """The markers :func:`simulate_gaps` may remove samples of.

    Parameters
    ----------
    motion
        The clip.
    ml
        With a run length, only the markers that can take a run of it (``ml`` + 2 frames
        observed in a row): ``ml`` hits at most this many markers, whatever ``markers``
        asks for.

    Returns
    -------
    np.ndarray
        Indices of the fillable markers with at least one observed sample (and room for
        the run).
    """
    candidates = np.flatnonzero(motion.fillable & motion.observed.any(axis=0))
    if ml is None or ml < 1:
        return candidates
    return np.array([j for j in candidates.tolist()
                     if _run_starts(motion.observed[:, j], ml).size], dtype=np.int64)


def channel_simulation_candidates(motion: Motion, ml: int | None = None) -> np.ndarray:
    """The joints (indices into ``motion.labels``) :func:`simulate_channel_gaps` may hit.

    Parameters
    ----------
    motion
        A clip read from a BVH or AMC file.

    Returns
    -------
    np.ndarray
        Indices of the joints that own channels and have a frame with all of them observed.
    """
    joints, _, _, _, proxy = _joint_proxy(motion)
    return np.asarray(joints)[simulation_candidates(proxy, ml)]


def _joint_proxy(motion: Motion):
    """A skeleton clip's joints that own channels as a Motion of "markers" (their channels
    all observed), with the channel values, mask and columns it was built from."""
    from . import formats

    module = formats.format_module(motion.path) if motion.path is not None else None
    if module is None or not hasattr(module, "channels"):
        raise ParameterError("channel gaps need a clip read from a BVH or AMC file")
    values, observed = module.channels(motion)
    skeleton = motion.source.state.skeleton
    columns = [list(r) + list(t) for r, t in zip(skeleton.rotation_columns,
                                                 skeleton.translation_columns)]
    joints = [j for j, cols in enumerate(columns) if cols]
    joint_observed = np.stack([observed[:, columns[j]].all(axis=1) for j in joints], axis=1)
    # The clip's path, so that an error about the proxy names the file.
    proxy = Motion(np.zeros(joint_observed.shape + (3,)), joint_observed,
                   tuple(motion.labels[j] for j in joints), motion.rate, path=motion.path)
    return joints, values, observed, columns, proxy


def joint_samples_observed(motion: Motion) -> np.ndarray:
    """(frames, joints) mask of a BVH or AMC clip's joints that own channels: True where
    every channel of the joint is observed (what the channel protocols remove)."""
    return _joint_proxy(motion)[4].observed


def simulate_channel_gaps(motion: Motion, *, mr: float | None = None, ml: int | None = None,
                          markers: int | None = None, seed: int | None = None) -> Motion:
    """The paper's protocols on a skeleton clip (BVH, AMC), removing joint channels.

    The "markers" of the protocols are the joints that own channels: a removed joint sample
    loses all its channels in that frame (written back as ``nan`` cells). The positions of
    the clip follow by forward kinematics.
    """
    from . import formats

    joints, values, observed, columns, proxy = _joint_proxy(motion)
    module = formats.format_module(motion.path)
    removed = proxy.observed & ~simulate_gaps(proxy, mr=mr, ml=ml, markers=markers,
                                              seed=seed).observed
    new_observed = observed.copy()
    for k, j in enumerate(joints):
        new_observed[:, columns[j]] &= ~removed[:, k, None]
    return module.with_channels(motion, values, new_observed)
