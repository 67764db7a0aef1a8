import warnings

import pytest

from mocapfill.errors import FormatError, ParameterError
from mocapfill.pipeline import repair

from .helpers import smooth_clip, with_gap

pytest.importorskip("matplotlib", reason="plotting is the optional 'plot' extra")

from mocapfill.plot import plot, time_axis  # noqa: E402


@pytest.fixture
def clips():
    gapped = with_gap(with_gap(smooth_clip(200, 6), 1, 50, 90), 4, 120, 130)
    return gapped, repair(gapped).motion


@pytest.mark.parametrize("suffix, magic", [(".png", b"\x89PNG"), (".svg", b"<?xml"),
                                           (".html", b"<!DOCTYPE html>")])
def test_plot_writes_each_format(tmp_path, clips, suffix, magic):
    out = tmp_path / f"p{suffix}"
    plotted = plot(*clips, out)
    assert out.read_bytes().startswith(magic)
    assert plotted == ["MK01", "MK04"]  # by default the markers that had gaps


def test_plot_selects_markers_by_glob(tmp_path, clips):
    assert plot(clips[0], None, tmp_path / "p.svg", markers=("MK0[23]",)) == ["MK02", "MK03"]


def test_plot_rejects_unknown_suffix_and_unmatched_marker(tmp_path, clips):
    with pytest.raises(FormatError):
        plot(*clips, tmp_path / "p.jpg")
    with pytest.raises(ParameterError):
        plot(*clips, tmp_path / "p.png", markers=("NOPE",))


def test_plot_refuses_a_missing_folder_or_a_folder_as_output(tmp_path, clips):
    (tmp_path / "folder.png").mkdir()
    with pytest.raises(FormatError, match="output folder .*nodir does not exist"):
        plot(*clips, tmp_path / "nodir" / "p.png")
    with pytest.raises(FormatError, match="is a folder"):
        plot(*clips, tmp_path / "folder.png")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["folder.png"]   # no temporaries


def test_a_clip_without_a_rate_is_plotted_against_frame_numbers(tmp_path, clips,
                                                                monkeypatch):
    # 0 Hz (a C3D without POINT:RATE, an AMC, a TRC or CSV stating none): the time axis
    # divided by it, 0/0 for the first frame and inf for the rest.
    import matplotlib.pyplot as plt

    gapped, repaired = (clip.replace(rate=0.0, first_frame=11) for clip in clips)
    values, label = time_axis(gapped)
    assert label == "frame (no frame rate known)"
    assert values.tolist() == list(range(11, 211))
    assert time_axis(clips[0])[1] == "time (s)"
    drawn = []
    close = plt.close
    monkeypatch.setattr(plt, "close", lambda fig: (drawn.append(fig), close(fig)))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert plot(gapped, repaired, tmp_path / "p.png") == ["MK01", "MK04"]
    axes = drawn[0].axes
    assert axes[-1].get_xlabel() == "frame (no frame rate known)"
    assert axes[0].get_xlim()[0] <= 11 and axes[0].get_xlim()[1] >= 210
