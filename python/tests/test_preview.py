"""write_preview: the 3D preview page of an excite output folder and of a trajectory CSV."""

import pathlib

import pytest

import idexp

ROOT = pathlib.Path(__file__).resolve().parents[2]


def test_write_preview_for_a_folder_and_a_csv(tmp_path):
    r = idexp.excite(str(ROOT / "designs/excite_ur5.toml"), time_limit=5)
    folder = tmp_path / "ur5"
    r.write(str(folder))
    page = pathlib.Path(idexp.write_preview(str(folder)))
    assert page == folder / "preview.html"
    html = page.read_text()
    assert html.startswith("<!doctype html>") and '"robot":"ur5"' in html
    out = tmp_path / "csv"
    page2 = pathlib.Path(
        idexp.write_preview(str(folder / "trajectory.csv"), robot=str(ROOT / "designs/robots/ur5.toml"), out=str(out))
    )
    assert page2 == out / "preview.html" and page2.stat().st_size > 500_000


def test_write_preview_refuses_bad_input(tmp_path):
    with pytest.raises(ValueError, match="fps"):
        idexp.write_preview(str(tmp_path), fps=0)
    with pytest.raises(ValueError, match="not a folder"):
        idexp.write_preview(str(tmp_path / "nothing.csv"))
    with pytest.raises(idexp.IdexpError, match="design.json"):
        idexp.write_preview(str(tmp_path))
