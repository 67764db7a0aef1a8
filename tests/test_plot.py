import pytest

from mocapfill.errors import FormatError, ParameterError
from mocapfill.pipeline import repair

from .helpers import smooth_clip, with_gap

pytest.importorskip("matplotlib", reason="plotting is the optional 'plot' extra")

from mocapfill.plot import plot  # noqa: E402


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
