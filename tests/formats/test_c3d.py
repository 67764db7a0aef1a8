"""C3D reader and patch writer: generated files in every storage, then the real files."""
from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import threading
import tracemalloc
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mocapfill import formats
from mocapfill.errors import FormatError
from mocapfill.formats import c3d, trc
from mocapfill.gaps import simulate_gaps
from mocapfill.motion import Motion

from ..conftest import shared_file, shared_files
from .c3d_fixtures import c3d_bytes, write_c3d

STORAGES = [(proc, scale) for proc in ("intel", "dec", "mips") for scale in (-0.1, 0.1)]
STORAGE_IDS = [f"{proc}-{'float' if scale < 0 else 'int'}" for proc, scale in STORAGES]


def walk(n_frames: int = 40, n_points: int = 5, seed: int = 0) -> np.ndarray:
    """Smooth trajectories in mm, well inside the int16 range at scale 0.1."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 2 * np.pi, n_frames)[:, None, None]
    base = rng.uniform(-1000, 1000, (1, n_points, 3))
    return base + 100 * np.sin(t + rng.uniform(0, 6, (1, n_points, 3)))


def gapped_file(tmp_path: Path, processor: str = "intel", scale: float = -0.1,
                analog_channels: int = 3, **kwargs) -> tuple[Path, np.ndarray, np.ndarray]:
    """A file with residual -1 gaps (and a NaN gap for float storage) plus analog words."""
    positions = walk()
    residuals = np.full(positions.shape[:2], 2.0)
    residuals[5:12, 1] = -1
    residuals[20:23, 3] = -1
    if scale < 0:
        positions[30:33, 2] = np.nan
    positions[residuals < 0] = 0.0
    analog = np.arange(positions.shape[0] * analog_channels * 2).reshape(positions.shape[0], -1)
    path = write_c3d(tmp_path / f"gapped-{processor}-{scale}.c3d", positions, residuals,
                     processor=processor, scale=scale, analog=analog % 3000,
                     analog_samples=2, **kwargs)
    observed = (residuals >= 0) & np.isfinite(positions).all(axis=2)
    return path, positions, observed


def fill_by_interpolation(motion: Motion) -> Motion:
    """Fill every missing sample of fillable markers seen at least once (ends held)."""
    positions, observed = motion.positions.copy(), motion.observed.copy()
    frames = np.arange(motion.n_frames)
    for j in np.flatnonzero(motion.fillable):
        seen = motion.observed[:, j]
        if seen.all() or not seen.any():
            continue
        for axis in range(3):
            positions[~seen, j, axis] = np.interp(frames[~seen], frames[seen],
                                                  positions[seen, j, axis])
        observed[:, j] = True
    return motion.with_positions(positions, observed)


def assert_only_samples_changed(source, patched: bytes, samples: np.ndarray) -> np.ndarray:
    """Assert ``patched`` is the file of ``source`` but in the records of the (frames,
    points) ``samples``; returns where those records start."""
    original = source.path.read_bytes()
    assert len(patched) == len(original)
    assert patched[:source.data_start] == original[:source.data_start]
    record = 4 * source.word_size
    allowed = np.zeros(len(original), bool)
    frames, markers = np.nonzero(samples)
    starts = (source.data_start + frames * source.frame_stride
              + source.point_index[markers] * record)
    allowed[starts[:, None] + np.arange(record)] = True
    changed = np.frombuffer(patched, np.uint8) != np.frombuffer(original, np.uint8)
    assert not (changed & ~allowed).any(), "bytes outside those samples changed"
    return starts


def assert_only_filled_samples_changed(before: Motion, after: Motion, written: Path) -> None:
    """The byte invariant of the patch writer, plus a decode of what was written."""
    source = before.source
    filled = after.observed & ~source.observed & source.fillable
    patched = written.read_bytes()
    starts = assert_only_samples_changed(source, patched, filled)
    record = 4 * source.word_size
    fourth = np.frombuffer(patched, np.uint8)[starts[:, None] + np.arange(record - source.word_size,
                                                                          record)]
    assert (fourth == 0).all(), "filled samples must carry residual word 0"
    back = c3d.read(written, zero_is_missing="on" if source.zeros_are_gaps else "off")
    np.testing.assert_array_equal(back.observed, source.observed | filled)
    tolerance = source.scale / 2 * 1.0001 if not source.is_float else 0.0
    np.testing.assert_allclose(back.positions[filled], after.positions[filled], rtol=1e-6,
                               atol=tolerance + 1e-9)
    kept = source.observed
    np.testing.assert_array_equal(back.positions[kept], before.positions[kept])


def ezc3d_points(path: Path) -> np.ndarray:
    """(frames, points, 3) positions as ezc3d reads them (NaN where invalid)."""
    ezc3d = pytest.importorskip("ezc3d")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return ezc3d.c3d(str(path))["data"]["points"][:3].transpose(2, 1, 0)


# --------------------------------------------------------------------------- reading


@pytest.mark.parametrize(("processor", "scale"), STORAGES, ids=STORAGE_IDS)
def test_reads_every_processor_and_storage(tmp_path, processor, scale):
    path, positions, observed = gapped_file(tmp_path, processor, scale)
    motion = c3d.read(path)
    np.testing.assert_array_equal(motion.observed, observed)
    atol = 0.05 + 1e-6 if scale > 0 else 1e-3
    np.testing.assert_allclose(motion.positions[observed], positions[observed], atol=atol)
    assert np.isnan(motion.positions[~observed]).all()
    assert motion.labels == ("M1", "M2", "M3", "M4", "M5")
    assert (motion.rate, motion.units, motion.first_frame) == (100.0, "mm", 1)
    assert motion.source.processor == processor and motion.source.is_float == (scale < 0)


def test_nan_coordinate_with_valid_residual_is_missing(tmp_path):
    positions = walk()
    positions[3, 0, 1] = np.nan                       # ezc3d writes gaps like this
    motion = c3d.read(write_c3d(tmp_path / "nan.c3d", positions))
    assert not motion.observed[3, 0] and motion.observed.sum() == motion.observed.size - 1


def test_labels_past_255_come_from_labels2(tmp_path):
    positions = walk(n_frames=3, n_points=300)
    motion = c3d.read(write_c3d(tmp_path / "many.c3d", positions))
    assert motion.n_markers == 300 and motion.labels[255:257] == ("M256", "M257")
    assert len(set(motion.labels)) == 300


def test_extra_empty_and_duplicate_labels_are_made_unique(tmp_path):
    labels = ["LASI", "", "LASI", "LASI_2", "LASI"]
    motion = c3d.read(write_c3d(tmp_path / "dup.c3d", walk(n_points=7), labels=labels))
    assert motion.labels == ("LASI", "POINT2", "LASI_3", "LASI_2", "LASI_4", "POINT6", "POINT7")


@pytest.mark.parametrize(("stored", "expected"),
                         [("mm", "mm"), ("mete", "m"), ("m", "m"), ("meters", "m"),
                          ("cm", "cm"), ("", "mm"), ("in/0.45", "in/0.45")])
def test_units_are_normalised(tmp_path, stored, expected):
    motion = c3d.read(write_c3d(tmp_path / "u.c3d", walk(n_points=1), units=stored))
    assert motion.units == expected


def test_rate_and_first_frame_come_from_the_file(tmp_path):
    path = write_c3d(tmp_path / "r.c3d", walk(n_points=1), rate=240.0, first_frame=244)
    motion = c3d.read(path)
    assert (motion.rate, motion.first_frame, motion.n_frames) == (240.0, 244, 40)


def test_model_outputs_are_not_fillable_with_or_without_subject_prefix(tmp_path):
    labels = ["Bob:LASI", "Bob:LKneeAngles", "Bob:LHipPower", "RKneeMoment", "RASI"]
    groups = {"POINT": {"ANGLES": ["LKneeAngles"], "POWERS": ["Bob:LHipPower"],
                        "MOMENTS": ["Bob:RKneeMoment"]}}
    motion = c3d.read(write_c3d(tmp_path / "m.c3d", walk(), labels=labels, groups=groups))
    np.testing.assert_array_equal(motion.fillable, [True, False, False, False, True])


def test_a_repeated_model_output_label_is_a_model_output_each_time(tmp_path):
    # Read as LKneeAngles_2 the second time, which no list names: that copy was filled.
    labels = ["LKNE", "LKneeAngles", "RKNE", "LKneeAngles"]
    groups = {"POINT": {"ANGLES": ["LKneeAngles"]}}
    motion = c3d.read(write_c3d(tmp_path / "d.c3d", walk(n_points=4), labels=labels,
                                groups=groups))
    assert motion.labels[3] == "LKneeAngles_2"
    np.testing.assert_array_equal(motion.fillable, [True, False, True, False])


def test_points_of_the_types_the_file_declares_are_model_outputs(tmp_path):
    # Vicon's POINT:TYPE_GROUPS pairs each list with its type; MODELED_MARKERS holds the
    # joint centres a model computes (pyCGM2, c3d.org Sample00), not measured markers.
    labels = ["LASI", "RASI", "LHJC", "LKneeAngles", "LPSI"]
    groups = {"POINT": {"TYPE_GROUPS": ["ANGLES", "ANGLE", "MODELED_MARKERS",
                                        "MODELED_MARKER", "MARKERS", "MARKER"],
                        "ANGLES": ["LKneeAngles"], "MODELED_MARKERS": ["LHJC"],
                        "MARKERS": ["LASI", "RASI"]}}
    motion = c3d.read(write_c3d(tmp_path / "t.c3d", walk(), labels=labels, groups=groups))
    np.testing.assert_array_equal(motion.fillable, [True, True, False, False, True])
    # Undeclared, a list of that name is read as any other parameter.
    del groups["POINT"]["TYPE_GROUPS"]
    motion = c3d.read(write_c3d(tmp_path / "u.c3d", walk(), labels=labels, groups=groups))
    np.testing.assert_array_equal(motion.fillable, [True, True, True, False, True])


def test_a_zero_point_rate_takes_the_headers(tmp_path):
    # As POINT:SCALE 0 does; 0 Hz ("not known") only where the header has none either.
    path = write_c3d(tmp_path / "r.c3d", walk(n_points=1), rate=100.0,
                     groups={"POINT": {"RATE": 0.0}})
    assert c3d.read(path).rate == 100.0
    path = write_c3d(tmp_path / "z.c3d", walk(n_points=1), rate=0.0)
    assert c3d.read(path).rate == 0.0


def test_a_clip_of_no_frames_with_a_padded_data_block_reads_no_frames(tmp_path):
    # The header and POINT:FRAMES say 0; the data block's 512 bytes of padding were read
    # as 10 frames of observed zeros.
    data = bytearray(c3d_bytes(walk(n_frames=1, n_points=3),
                               groups={"POINT": {"FRAMES": 0}}))
    data[8:10] = (0).to_bytes(2, "little")          # header: frames 1 to 0
    path = tmp_path / "empty.c3d"
    path.write_bytes(bytes(data))
    motion = c3d.read(path)
    assert (motion.n_frames, motion.n_markers) == (0, 3)


# --------------------------------------------------------------------------- zero gaps


def zero_gap_file(tmp_path: Path, fourth: float, **kwargs) -> Path:
    positions = walk()
    residuals = np.full(positions.shape[:2], 3.0)
    positions[10:14, 2] = 0.0
    residuals[10:14, 2] = fourth
    positions[20, 1, 0] = 0.0                         # one zero coordinate: never a gap
    return write_c3d(tmp_path / "zeros.c3d", positions, residuals, **kwargs)


def test_qualisys_company_turns_zero_gaps_on(tmp_path):
    path = zero_gap_file(tmp_path, 3.0, groups={"MANUFACTURER": {"COMPANY": "Qualisys"}})
    motion = c3d.read(path)
    assert not motion.observed[10:14, 2].any() and motion.observed.sum() == 40 * 5 - 4


def test_qtm_zero_signature_turns_zero_gaps_on_without_manufacturer(tmp_path):
    motion = c3d.read(zero_gap_file(tmp_path, 65535.0))
    assert not motion.observed[10:14, 2].any() and motion.observed[20, 1]


def test_zeros_stay_observed_in_other_files_unless_asked(tmp_path):
    path = zero_gap_file(tmp_path, 3.0)
    assert c3d.read(path).observed.all()
    assert not c3d.read(path, zero_is_missing="on").observed[10:14, 2].any()
    qtm = zero_gap_file(tmp_path, 65535.0)
    assert c3d.read(qtm, zero_is_missing="off").observed.all()


def test_zero_gaps_of_model_outputs_stay_observed(tmp_path):
    path = zero_gap_file(tmp_path, 65535.0, labels=["A", "B", "LKneeAngles", "C", "D"],
                         groups={"POINT": {"ANGLES": ["LKneeAngles"]}})
    assert c3d.read(path, zero_is_missing="on").observed[:, 2].all()


def test_unknown_zero_is_missing_value_is_rejected(tmp_path):
    with pytest.raises(ValueError, match="zero_is_missing"):
        c3d.read(zero_gap_file(tmp_path, 3.0), zero_is_missing="yes")


# --------------------------------------------------------------------------- broken files


def test_empty_file_is_a_format_error(tmp_path):
    path = tmp_path / "empty.c3d"
    path.write_bytes(b"")
    with pytest.raises(FormatError, match="empty"):
        c3d.read(path)


def test_text_file_named_c3d_is_a_format_error(tmp_path):
    path = tmp_path / "text.c3d"
    path.write_text("frame,x,y,z\n1,2,3,4\n" * 40)
    with pytest.raises(FormatError, match="not a C3D file") as err:
        c3d.read(path)
    assert str(path) in str(err.value) and "\n" not in str(err.value)


def test_truncated_file_names_frames_present(tmp_path):
    path, _, _ = gapped_file(tmp_path)
    data = path.read_bytes()
    motion = c3d.read(path)
    cut = motion.source.data_start + 10 * motion.source.frame_stride + 7
    path.write_bytes(data[:cut])
    with pytest.raises(FormatError, match="truncated: 10 of 40 frames present"):
        c3d.read(path)


@pytest.mark.parametrize("forge", ["header_frames", "point_used", "long_frames"])
def test_forged_counts_fail_without_allocating(tmp_path, forge):
    positions = walk()
    if forge == "point_used":
        data = c3d_bytes(positions, point_used=65535)
    elif forge == "long_frames":
        data = bytearray(c3d_bytes(positions, groups={"POINT": {"LONG_FRAMES": 3.0e9}}))
        data[8:10] = (0xFFFF).to_bytes(2, "little")      # header last frame: "more than fits"
    else:
        data = bytearray(c3d_bytes(positions))
        data[8:10] = (60000).to_bytes(2, "little")
    path = tmp_path / "forged.c3d"
    path.write_bytes(bytes(data))
    # The refusal must come from the counts and the file's size, before any buffer for the
    # frames declared: its peak is ~13 kB (numpy's allocations are traced too), a buffer
    # for the forged counts at least 4.8 MB (60000 frames of 5 points, 16 bytes each).
    tracemalloc.start()
    try:
        with pytest.raises(FormatError, match="truncated"):
            c3d.read(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 1_000_000


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(st.integers(0, 2047), st.integers(0, 255)), min_size=1, max_size=12))
def test_corrupt_header_or_parameters_give_a_motion_or_a_format_error(edits):
    data = bytearray(c3d_bytes(walk(n_frames=8, n_points=3), analog=np.ones((8, 4))))
    for offset, value in edits:
        data[offset % 1536] = value
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "fuzzed.c3d"
        path.write_bytes(bytes(data))
        try:
            assert isinstance(c3d.read(path), Motion)
        except FormatError as err:
            assert "\n" not in str(err)


# --------------------------------------------------------------------------- patch writer


@pytest.mark.parametrize(("processor", "scale"), STORAGES, ids=STORAGE_IDS)
def test_patch_changes_only_the_filled_samples(tmp_path, processor, scale):
    path, _, _ = gapped_file(tmp_path, processor, scale)
    before = c3d.read(path)
    after = fill_by_interpolation(before)
    out = tmp_path / "out.c3d"
    formats.write(after, out)
    assert_only_filled_samples_changed(before, after, out)
    assert out.read_bytes() != path.read_bytes()


@pytest.mark.parametrize(("processor", "scale"), [s for s in STORAGES if s[0] != "mips"],
                         ids=[i for i in STORAGE_IDS if not i.startswith("mips")])
def test_patched_values_read_back_the_same_in_ezc3d(tmp_path, processor, scale):
    path, _, _ = gapped_file(tmp_path, processor, scale)
    after = fill_by_interpolation(c3d.read(path))
    out = tmp_path / "out.c3d"
    c3d.write(after, out)
    ours = c3d.read(out)
    theirs = ezc3d_points(out)
    np.testing.assert_array_equal(~np.isnan(theirs).any(axis=2), ours.observed)
    np.testing.assert_allclose(theirs[ours.observed], ours.positions[ours.observed], atol=1e-3)


def test_observed_samples_are_never_rewritten(tmp_path):
    path, _, _ = gapped_file(tmp_path)
    before = c3d.read(path)
    shifted = np.where(before.observed[:, :, None], before.positions + 50.0, 1.0)
    out = tmp_path / "out.c3d"
    c3d.write(before.with_positions(shifted, np.ones_like(before.observed)), out)
    back = c3d.read(out)
    np.testing.assert_array_equal(back.positions[before.observed],
                                  before.positions[before.observed])
    np.testing.assert_allclose(back.positions[~before.observed], 1.0, rtol=1e-6)


def test_model_outputs_are_never_patched(tmp_path):
    residuals = np.ones((40, 5))
    residuals[5:9, :] = -1
    path = write_c3d(tmp_path / "m.c3d", walk(), residuals, labels=["A", "B", "LHipPower",
                                                                    "C", "D"],
                     groups={"POINT": {"POWERS": ["LHipPower"]}})
    before = c3d.read(path)
    everything = np.nan_to_num(before.positions, nan=5.0)
    out = tmp_path / "out.c3d"
    c3d.write(before.with_positions(everything, np.ones_like(before.observed)), out)
    back = c3d.read(out)
    assert not back.observed[5:9, 2].any() and back.observed[5:9, [0, 1, 3, 4]].all()


@pytest.mark.parametrize("suffix", [".trc", ".csv"])
def test_model_outputs_are_left_out_of_a_trc_or_csv(tmp_path, suffix):
    # A TRC or CSV holds markers: an angle written there would read back as a marker,
    # be filled by a later repair and serve as evidence for the real markers.
    residuals = np.ones((40, 5))
    residuals[5:9, 2] = -1
    path = write_c3d(tmp_path / "m.c3d", walk(), residuals,
                     labels=["A", "LKneeAngles", "B", "LHipPower", "C"],
                     groups={"POINT": {"ANGLES": ["LKneeAngles"], "POWERS": ["LHipPower"]}})
    motion = c3d.read(path)
    out = tmp_path / f"out{suffix}"
    notes = formats.write(motion, out)
    back = formats.read(out)
    assert back.labels == ("A", "B", "C")
    np.testing.assert_allclose(back.positions, motion.positions[:, [0, 2, 4]], rtol=1e-6)
    np.testing.assert_array_equal(back.observed, motion.observed[:, [0, 2, 4]])
    assert len(notes) == 1 and notes[0].startswith("2 point(s) that are not marker "
                                                   "trajectories")


def test_model_outputs_stay_in_a_c3d_and_an_npz(tmp_path):
    path = write_c3d(tmp_path / "m.c3d", walk(), labels=["A", "LHipPower", "B", "C", "D"],
                     groups={"POINT": {"POWERS": ["LHipPower"]}})
    motion = c3d.read(path)
    for suffix in (".c3d", ".npz"):
        assert formats.write(motion, tmp_path / f"out{suffix}") == ()
        back = formats.read(tmp_path / f"out{suffix}")
        assert back.labels == motion.labels and back.fillable.tolist() == [1, 0, 1, 1, 1]


def test_nothing_to_fill_copies_the_file(tmp_path):
    path, _, _ = gapped_file(tmp_path)
    out = tmp_path / "out.c3d"
    c3d.write(c3d.read(path), out)
    assert out.read_bytes() == path.read_bytes()


def test_integer_overflow_is_refused_not_wrapped(tmp_path):
    path, _, _ = gapped_file(tmp_path, scale=0.1)
    before = c3d.read(path)
    huge = np.where(before.observed[:, :, None], before.positions, 5000.0)  # > 3276.7 mm
    with pytest.raises(FormatError, match="overflow the int16 range"):
        c3d.write(before.with_positions(huge, np.ones_like(before.observed)),
                  tmp_path / "out.c3d")


def test_end_extrapolation_of_a_real_integer_c3d_is_written(tmp_path):
    # A marker seen up to 2632 mm (limit 2637.6 at this scale): its end fill went to 2646
    # and the writer refused the clip. Now written, observed words byte for byte.
    path = shared_file("c3d/btk-sample04__sub_labels.c3d")
    before = c3d.read(path)
    assert before.source.value_range is not None
    out = tmp_path / "out.c3d"
    result = subprocess.run([sys.executable, "-m", "mocapfill", "repair", "--ends",
                             "extrapolate", str(path), str(out)], capture_output=True,
                            text=True)
    assert result.returncode == 0, result.stderr
    after = c3d.read(out)
    assert after.observed.sum() > before.observed.sum()
    low, high = before.source.value_range
    assert low <= np.nanmin(after.positions) and np.nanmax(after.positions) <= high
    np.testing.assert_array_equal(after.positions[before.observed],
                                  before.positions[before.observed])
    assert_only_samples_changed(before.source, out.read_bytes(),
                                after.observed & ~before.observed)


def test_an_interior_fill_past_the_int16_limit_does_not_refuse_the_clip(tmp_path):
    # A marker that peaks near the limit (3270 mm at scale 0.1, limit 3276.7) on both
    # sides of a gap: the spline-like fill overshoots to about 3295 mm and the writer
    # refused the whole clip (exit 123), as it did end fills before they were clamped.
    n = 120
    positions = walk(n_frames=n)
    frames = np.arange(n)
    positions[:, 0, 0] = np.where(frames <= 40, 3270 - (40 - frames), 3270 - (frames - 80))
    residuals = np.full(positions.shape[:2], 2.0)
    residuals[41:80, 0] = -1
    positions[residuals < 0] = 0.0
    path = write_c3d(tmp_path / "peak.c3d", positions, residuals, scale=0.1)
    before = c3d.read(path)
    out = tmp_path / "out.c3d"
    result = subprocess.run([sys.executable, "-m", "mocapfill", "repair", str(path),
                             str(out), "--max-jump", "0"], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    after = c3d.read(out)
    assert after.observed[41:80, 0].all()
    low, high = before.source.value_range
    assert low <= np.nanmin(after.positions) and np.nanmax(after.positions) <= high
    assert_only_samples_changed(before.source, out.read_bytes(),
                                after.observed & ~before.observed)


def test_changed_source_file_is_not_patched(tmp_path):
    path, _, _ = gapped_file(tmp_path)
    before = c3d.read(path)
    path.write_bytes(path.read_bytes()[:-1] + b"\x01")
    with pytest.raises(FormatError, match="changed since it was read"):
        c3d.write(fill_by_interpolation(before), tmp_path / "out.c3d")


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="FIFOs need a POSIX system")
def test_repair_of_a_c3d_read_from_a_fifo_patches_the_bytes_read(tmp_path):
    # A FIFO can be read once: re-reading it to patch blocked forever. The repair runs in
    # a child process with a timeout so that a regression fails instead of hanging.
    path, _, _ = gapped_file(tmp_path)
    fifo = tmp_path / "piped.c3d"
    os.mkfifo(fifo)
    feeder = threading.Thread(target=fifo.write_bytes, args=(path.read_bytes(),), daemon=True)
    feeder.start()
    piped, regular = tmp_path / "from-fifo.c3d", tmp_path / "from-file.c3d"
    done = subprocess.run([sys.executable, "-m", "mocapfill", "repair", str(fifo), str(piped)],
                          capture_output=True, text=True, timeout=60)
    feeder.join(timeout=5)
    assert done.returncode == 0, done.stderr
    done = subprocess.run([sys.executable, "-m", "mocapfill", "repair", str(path), str(regular)],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert piped.read_bytes() == regular.read_bytes()
    assert piped.read_bytes() != path.read_bytes()      # the gaps were filled in the patch
    assert c3d.read(piped).observed.sum() > c3d.read(path).observed.sum()


def test_reshaped_motion_cannot_be_patched(tmp_path):
    path, _, _ = gapped_file(tmp_path)
    before = c3d.read(path)
    shorter = Motion(before.positions[:10], before.observed[:10], before.labels, before.rate,
                     source=before.source)
    with pytest.raises(FormatError, match="cannot patch"):
        c3d.write(shorter, tmp_path / "out.c3d")


# --------------------------------------------------------------------------- new files


def in_memory_motion(n_markers: int = 6, first_frame: int = 1) -> Motion:
    positions = walk(n_frames=30, n_points=n_markers)
    observed = np.ones(positions.shape[:2], bool)
    observed[4:9, 0] = False
    return Motion(positions, observed, tuple(f"Mk{i}" for i in range(n_markers)), 120.0, "m",
                  first_frame=first_frame)


def test_new_file_round_trips_through_our_reader(tmp_path):
    motion = in_memory_motion(first_frame=7)
    out = tmp_path / "new.c3d"
    c3d.write(motion, out)
    back = c3d.read(out)
    np.testing.assert_array_equal(back.observed, motion.observed)
    np.testing.assert_array_equal(back.positions[back.observed],
                                  motion.positions.astype(np.float32)[motion.observed])
    assert (back.labels, back.rate, back.units, back.first_frame) == (
        motion.labels, 120.0, "m", 7)
    assert back.source.processor == "intel" and back.source.is_float


@pytest.mark.parametrize("first_frame", [0, 65_520, 70_000])     # 0: OptiTrack counts so
def test_new_file_numbered_from_0_or_past_65535_keeps_every_frame_and_its_number(
        tmp_path, first_frame):
    # The header's 16-bit frame words cannot hold numbers past 65535; TRIAL's fields can.
    motion = in_memory_motion(first_frame=first_frame)
    out = tmp_path / "late.c3d"
    c3d.write(motion, out)
    back = c3d.read(out)
    assert (back.n_frames, back.first_frame) == (30, first_frame)
    np.testing.assert_array_equal(back.observed, motion.observed)
    assert ezc3d_points(out).shape[0] == 30


@pytest.mark.parametrize("first_frame", [-5, 2**40])
def test_a_first_frame_no_c3d_holds_is_written_as_1_with_a_note(tmp_path, first_frame):
    # An NPZ (or a library caller) may number frames from anywhere; TRIAL holds 0 to
    # 2³² − 1.
    motion = in_memory_motion(first_frame=first_frame)
    notes = formats.write(motion, tmp_path / "a.c3d")
    assert notes == (f"first frame {first_frame} does not fit a C3D (0 to "
                     f"{0xFFFFFFFF - 30}): frames numbered from 1",)
    assert c3d.read(tmp_path / "a.c3d").first_frame == 1
    kept = formats.write(in_memory_motion(first_frame=70_000), tmp_path / "b.c3d")
    assert not any("first frame" in note for note in kept)


def test_new_file_stores_gaps_as_zero_with_residual_minus_one(tmp_path):
    out = tmp_path / "new.c3d"
    c3d.write(in_memory_motion(), out)
    source = c3d.read(out).source
    start = source.data_start + 4 * source.frame_stride
    assert np.frombuffer(out.read_bytes()[start:start + 16], "<f4").tolist() == [0, 0, 0, -1]


@pytest.mark.parametrize("n_markers", [6, 300])
def test_new_file_reads_the_same_in_ezc3d(tmp_path, n_markers):
    motion = in_memory_motion(n_markers)
    out = tmp_path / "new.c3d"
    c3d.write(motion, out)
    theirs = ezc3d_points(out)
    np.testing.assert_array_equal(~np.isnan(theirs).any(axis=2), motion.observed)
    np.testing.assert_array_equal(theirs[motion.observed],
                                  motion.positions.astype(np.float32)[motion.observed])
    ezc3d = pytest.importorskip("ezc3d")
    labels = ezc3d.c3d(str(out))["parameters"]["POINT"]
    listed = labels["LABELS"]["value"] + (labels["LABELS2"]["value"] if n_markers > 255 else [])
    assert tuple(listed) == motion.labels


def test_new_file_refuses_a_value_past_the_float32_range(tmp_path):
    # float32 would store it as inf, which reads back as a gap: the value would be lost.
    motion = in_memory_motion()
    positions = motion.positions.copy()
    positions[2, 1, 0] = 1e39
    out = tmp_path / "huge.c3d"
    with pytest.raises(FormatError, match=r"\(1e\+39\) overflows the float32 range"):
        c3d.write(motion.with_positions(positions, motion.observed), out)
    assert not out.exists()


def test_new_file_writes_the_names_it_reads_back_with_a_note(tmp_path):
    # Empty, repeated and space-padded labels come back renamed from any C3D; a new file
    # holds those names already, and the note says so, as for a TRC or a CSV.
    motion = in_memory_motion(n_markers=5).replace(labels=("", "LASI", "LASI", " RASI ",
                                                           "POINT1"))
    out = tmp_path / "names.c3d"
    notes = formats.write(motion, out)
    expected = ("POINT1", "LASI", "LASI_2", "RASI", "POINT1_2")
    assert c3d.read(out).labels == expected
    assert tuple(pytest.importorskip("ezc3d").c3d(str(out))["parameters"]["POINT"]["LABELS"]
                 ["value"]) == expected
    assert notes == ("4 marker name(s) written as names a C3D reads back: '' -> 'POINT1', "
                     "'LASI' -> 'LASI_2', ...",)


def test_new_file_splits_long_labels_so_each_entry_fits_its_16_bit_offset(tmp_path):
    # 255 labels padded to a 170-byte one would be 43350 bytes: more than an entry holds.
    labels = [f"M{j}" for j in range(300)]
    labels[5] = "X" * 170
    motion = Motion(walk(n_frames=4, n_points=300), np.ones((4, 300), bool), labels, 100.0)
    out = tmp_path / "long_labels.c3d"
    c3d.write(motion, out)
    assert c3d.read(out).labels == tuple(labels)
    ezc3d = pytest.importorskip("ezc3d")
    point = ezc3d.c3d(str(out))["parameters"]["POINT"]
    listed = [name for key in ("LABELS", "LABELS2", "LABELS3", "LABELS4") if key in point
              for name in point[key]["value"]]
    assert listed == labels


def test_new_file_whose_labels_overflow_the_parameter_section_is_refused(tmp_path):
    labels = [f"Subject_With_A_Long_Name:marker_{j:05d}_left_side" for j in range(3000)]
    motion = Motion(np.ones((2, 3000, 3)), np.ones((2, 3000), bool), labels, 100.0)
    out = tmp_path / "many.c3d"
    with pytest.raises(FormatError, match="holds 255 blocks at most; write .trc or .csv"):
        c3d.write(motion, out)
    assert not out.exists()


def test_new_file_past_65535_frames_keeps_every_frame(tmp_path):
    positions = np.arange(70_000 * 3, dtype=float).reshape(70_000, 1, 3) % 1000
    out = tmp_path / "long.c3d"
    c3d.write(Motion(positions, np.ones((70_000, 1), bool), ("M",), 1000.0), out)
    back = c3d.read(out)
    assert back.n_frames == 70_000
    np.testing.assert_array_equal(back.positions, positions)


@pytest.mark.parametrize("n_frames", [65_535, 65_537])
def test_new_file_of_65535_frames_or_more_reads_no_extra_frames_in_ezc3d(tmp_path, n_frames):
    # POINT:FRAMES holds 65535 (-1 as an int16) there: ezc3d then reads frames up to the
    # end of the file, so block padding after the last frame came back as frames at 0, 0, 0.
    positions = np.full((n_frames, 2, 3), 5.0)
    out = tmp_path / "long.c3d"
    c3d.write(Motion(positions, np.ones((n_frames, 2), bool), ("A", "B"), 100.0), out)
    assert ezc3d_points(out).shape[0] == n_frames
    assert c3d.read(out).n_frames == n_frames


@pytest.mark.filterwarnings("ignore:No analog data found")
def test_new_file_reads_in_py_c3d(tmp_path):
    py_c3d = pytest.importorskip("c3d")
    out = tmp_path / "new.c3d"
    c3d.write(in_memory_motion(), out)
    with open(out, "rb") as handle:
        frames = [points for _, points, _ in py_c3d.Reader(handle).read_frames()]
    assert len(frames) == 30 and frames[5][0, 3] == -1 and frames[0][0, 3] == 0


@pytest.mark.filterwarnings("ignore:No analog data found")
def test_new_file_of_a_clip_without_a_rate_reads_in_py_c3d_and_ezc3d(tmp_path):
    # A 0 Hz clip (no rate known): the header's analog samples per frame must be 0 too,
    # or py-c3d refuses to open the file ("inconsistent analog rate"). (Its read_frames
    # divides by the rate, so it reads no 0 Hz file's frames, ours or any other.)
    py_c3d = pytest.importorskip("c3d")
    motion = in_memory_motion().replace(rate=0.0)
    out = tmp_path / "no_rate.c3d"
    c3d.write(motion, out)
    with open(out, "rb") as handle:
        assert py_c3d.Reader(handle).frame_count == 30
    assert ezc3d_points(out).shape[0] == 30
    assert c3d.read(out).rate == 0.0


# --------------------------------------------------------------------------- real files

QUICK = ["c3d/btk-sample01__Eb015pr.c3d", "c3d/btk-sample02__DEC_INT.C3D",
         "c3d/btk-sample02__sgi_real.c3d", "c3d/c3dorg-Sample26__Walking_Hybrid_1_1.c3d",
         "cmu/85_02.c3d", "c3d/btk-sample09__PlugInC3D.c3d"]
REAL = shared_files("c3d", ".c3d") + shared_files("cmu", ".c3d")
# Files we reject on purpose, with the reason the error must give.
REJECTED = {"ezc3d-Optotrak.c3d": "truncated: 29 of 1149 frames present"}
# ezc3d cannot read these (MIPS, a char OFFSET) or decodes them differently from both
# py-c3d and us (no POINT:SCALE/ANALOG:RATE); py-c3d is the independent reader there.
PY_C3D_REFERENCE = {"btk-sample01__Eb015si.c3d", "btk-sample01__Eb015sr.c3d",
                    "btk-sample02__sgi_int.c3d", "btk-sample02__sgi_real.c3d",
                    "btk-sample13__Dance.c3d", "btk-sample13__golfswing.c3d",
                    "btk-others__561xxa01_anonym.C3D", "btk-sample28__dynamic.C3D",
                    "btk-sample28__standing.C3D", "btk-sample28__type1.C3D"}


def repair_real_file(path: Path, tmp_path: Path) -> None:
    if path.name in REJECTED:
        with pytest.raises(FormatError, match=REJECTED[path.name]):
            c3d.read(path)
        return
    before = c3d.read(path)
    after = fill_by_interpolation(before)
    if not (after.observed & ~before.observed).any():
        # Nothing the file holds to fill (85_02, 85_12, Dance, ...): remove a few samples
        # first, so that fills are written and the bytes around them checked.
        simulated = simulate_gaps(before, ml=5, markers=3, seed=0)
        gapped = tmp_path / f"gapped-{path.name}"
        formats.write(simulated, gapped)
        assert_only_samples_changed(before.source, gapped.read_bytes(),
                                    before.observed & ~simulated.observed)
        before = c3d.read(gapped)
        np.testing.assert_array_equal(before.observed, simulated.observed)
        after = fill_by_interpolation(before)
    assert (after.observed & ~before.observed).any(), "nothing was filled"
    out = tmp_path / path.name
    formats.write(after, out)
    assert_only_filled_samples_changed(before, after, out)
    if path.name not in PY_C3D_REFERENCE:  # ezc3d decodes the patched file the same way
        written = c3d.read(out, zero_is_missing="off")
        theirs = ezc3d_points(out)
        np.testing.assert_array_equal(~np.isnan(theirs).any(axis=2), written.observed)
        np.testing.assert_allclose(theirs[written.observed], written.positions[written.observed],
                                   rtol=1e-5, atol=1e-4)


@pytest.mark.parametrize("relative", QUICK)
def test_real_file_patch_changes_only_filled_samples(relative, tmp_path):
    repair_real_file(shared_file(relative), tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("path", REAL, ids=[p.name for p in REAL])
def test_every_real_file_patch_changes_only_filled_samples(path, tmp_path):
    repair_real_file(path, tmp_path)


def reference_points(path: Path) -> np.ndarray:
    """Positions from an independent reader, NaN where it says the sample is invalid."""
    if path.name not in PY_C3D_REFERENCE:
        return ezc3d_points(path)
    py_c3d = pytest.importorskip("c3d")
    with open(path, "rb") as handle, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        frames = [points for _, points, _ in py_c3d.Reader(handle).read_frames()]
    points = np.array(frames, dtype=np.float64)
    return np.where(points[:, :, 3:4] < 0, np.nan, points[:, :, :3])


def assert_agrees_with_reference(path: Path) -> None:
    ours = c3d.read(path, zero_is_missing="off")
    theirs = reference_points(path)
    assert theirs.shape == ours.positions.shape
    np.testing.assert_array_equal(~np.isnan(theirs).any(axis=2), ours.observed)
    np.testing.assert_allclose(theirs[ours.observed], ours.positions[ours.observed],
                               rtol=1e-5, atol=1e-4)


@pytest.mark.parametrize("relative", ["c3d/btk-sample02__Dec_real.c3d", "cmu/85_02.c3d",
                                      "c3d/btk-sample02__sgi_int.c3d"])
def test_real_file_agrees_with_an_independent_reader(relative):
    assert_agrees_with_reference(shared_file(relative))


@pytest.mark.slow
@pytest.mark.parametrize("path", [p for p in REAL if p.name not in REJECTED],
                         ids=[p.name for p in REAL if p.name not in REJECTED])
def test_every_real_file_agrees_with_an_independent_reader(path):
    assert_agrees_with_reference(path)


@pytest.mark.parametrize(("family", "scale"), [("btk-sample01__Eb015", 0.0834),
                                               ("btk-sample02__", 0.2812)])
def test_same_trial_in_every_processor_and_storage_reads_the_same(family, scale):
    paths = [p for p in shared_files("c3d", ".c3d") if p.name.startswith(family)]
    if len(paths) < 6:
        pytest.skip(f"{family} files not available")
    motions = [c3d.read(p) for p in paths]
    assert {m.source.processor for m in motions} == {"intel", "dec", "mips"}
    assert {m.source.is_float for m in motions} == {True, False}
    reference = motions[0]
    for motion in motions[1:]:
        np.testing.assert_array_equal(motion.observed, reference.observed)
        assert motion.labels == reference.labels
        np.testing.assert_allclose(motion.positions[motion.observed],
                                   reference.positions[reference.observed], atol=scale)


def test_qualisys_zero_gaps_are_detected_in_sample26():
    path = shared_file("c3d/c3dorg-Sample26__Capture0002.c3d")
    auto, off = c3d.read(path), c3d.read(path, zero_is_missing="off")
    assert off.observed.all()
    gaps = ~auto.observed
    assert gaps.sum() == 818
    np.testing.assert_array_equal(off.positions[gaps], 0.0)


@pytest.mark.parametrize(("relative", "n_outputs"), [
    ("c3d/btk-sample09__PlugInC3D.c3d", 32), ("c3d/btk-PiG__PiG_Motion-FlatFoot-Full.c3d", 80),
    ("c3d/c3dorg-Sample00__Vicon__pyCGM2_lower_limb_CGM24_Walking01.c3d", 71)])
def test_vicon_model_outputs_are_not_fillable(relative, n_outputs):
    # pyCGM2's 71: 63 angles, forces, moments and powers, and the 8 joint centres of its
    # MODELED_MARKERS (LHJC_CGM_2.4 ...), a list its POINT:TYPE_GROUPS declares.
    motion = c3d.read(shared_file(relative))
    outputs = [label for label, ok in zip(motion.labels, motion.fillable) if not ok]
    assert len(outputs) == n_outputs
    assert any(label.rsplit(":", 1)[-1].endswith("Angles") for label in outputs)


def test_vicon_model_outputs_are_left_out_of_a_trc(tmp_path):
    motion = c3d.read(shared_file("c3d/btk-PiG__PiG_Motion-FlatFoot-Full.c3d"))
    out = tmp_path / "pig.trc"
    formats.write(motion, out)
    markers = [label for label, ok in zip(motion.labels, motion.fillable) if ok]
    assert formats.read(out).labels == tuple(trc.opensim_names(markers))


def test_a_new_c3d_keeps_which_points_are_not_markers(tmp_path):
    # A clip from an NPZ (or any other format) is written as a new file; its model
    # outputs must read back as model outputs, or a later repair fills them and takes
    # them as evidence for the markers.
    clip = Motion(walk(n_points=3), np.ones((40, 3), bool), ("A", "LKneeAngles", "B"), 100.0,
                  fillable=np.array([True, False, True]))
    out = tmp_path / "new.c3d"
    assert formats.write(clip, out) == ()
    back = c3d.read(out)
    assert back.labels == clip.labels and back.fillable.tolist() == [True, False, True]
    assert formats.write(clip.replace(fillable=np.ones(3, bool)), tmp_path / "all.c3d") == ()
    assert c3d.read(tmp_path / "all.c3d").fillable.all()


def test_a_new_c3d_lists_more_than_255_model_outputs(tmp_path):
    fillable = np.arange(600) % 7 == 0          # 514 outputs: SCALARS, SCALARS2, SCALARS3
    clip = Motion(np.zeros((3, 600, 3)), np.ones((3, 600), bool),
                  tuple(f"P{j}" for j in range(600)), 100.0, fillable=fillable)
    formats.write(clip, tmp_path / "big.c3d")
    np.testing.assert_array_equal(c3d.read(tmp_path / "big.c3d").fillable, fillable)


def test_vicon_model_outputs_survive_c3d_npz_c3d(tmp_path):
    motion = c3d.read(shared_file("c3d/btk-PiG__PiG_Motion-FlatFoot-Full.c3d"))
    formats.write(motion, tmp_path / "pig.npz")
    formats.write(formats.read(tmp_path / "pig.npz"), tmp_path / "back.c3d")
    back = c3d.read(tmp_path / "back.c3d")
    assert back.labels == motion.labels
    np.testing.assert_array_equal(back.fillable, motion.fillable)
    assert 0 < back.fillable.sum() < back.n_markers


def test_duplicate_real_labels_get_numbered_suffixes():
    motion = c3d.read(shared_file("c3d/ktk-duplicate_labels.c3d"))
    assert len(set(motion.labels)) == motion.n_markers
    assert {"CLAVD", "CLAVD_2", "CLAVD_3"} <= set(motion.labels)


def test_real_text_file_named_c3d_is_a_format_error():
    path = shared_file("bad/gait-raw-csv-text.c3d")
    with pytest.raises(FormatError) as err:
        formats.read(path)
    assert str(path) in str(err.value) and "\n" not in str(err.value)


def test_truncated_copy_of_a_real_file_is_a_format_error(tmp_path):
    data = shared_file("c3d/btk-sample01__Eb015pr.c3d").read_bytes()
    path = tmp_path / "cut.c3d"
    path.write_bytes(data[:len(data) // 2])
    with pytest.raises(FormatError, match=r"cut\.c3d: truncated: \d+ of 450 frames present"):
        formats.read(path)


def test_new_file_keeps_labels_outside_latin1_and_refuses_labels_past_255_bytes(tmp_path):
    from mocapfill import formats
    from mocapfill.errors import FormatError

    motion = in_memory_motion(4)
    names = ("左膝", "右膝", "Hüfte", "LASI")        # two would both have become '??'
    out = tmp_path / "names.c3d"
    formats.write(Motion(motion.positions, motion.observed, names, motion.rate, motion.units),
                  out)
    assert c3d.read(out).labels == names
    long_name = ("Marker" * 50,) + names[1:]
    with pytest.raises(FormatError, match=r"long\.c3d: POINT:LABELS 'MarkerMarker.*300 bytes"):
        formats.write(Motion(motion.positions, motion.observed, long_name, motion.rate,
                             motion.units), tmp_path / "long.c3d")
    assert not (tmp_path / "long.c3d").exists()
