"""gelrig.Shape: height maps from numpy frames, with a shape file `gelrig shape calibrate`
wrote on the real GelSight Mini ball presses; the same maps as the command's `.npy`."""

import os

import numpy as np
import pytest

import gelrig
from conftest import DATA, gelrig_cli


def ball_dir():
    d = DATA / "gelsight-mini-ball"
    if d.is_dir():
        return d
    if os.environ.get("GELRIG_REQUIRE_DATA") == "1":
        pytest.fail(f"{d} is absent and GELRIG_REQUIRE_DATA=1: put ../shared beside the checkout")
    pytest.skip(f"skipped: {d} is absent (CI has it; a fresh clone does not)")


@pytest.fixture(scope="module")
def shape_file(tmp_path_factory):
    d = ball_dir()
    out = tmp_path_factory.mktemp("shape") / "shape.yaml"
    text = gelrig_cli(
        ["shape", "calibrate", str(d), "--ball-diameter", "9.47mm", "--mm-per-px", "0.0634", "--out", str(out)]
    )
    assert "chosen: local-linear" in text
    return out


def test_height_maps_from_numpy_frames_match_the_command(shape_file, tmp_path):
    d = ball_dir()
    background = gelrig.read_image(d / "background.png")
    shape = gelrig.Shape.load(shape_file, background)
    assert shape.mm_per_px == pytest.approx(0.0634)
    assert [f["model"] for f in shape.figures] == ["local-linear", "lut"]
    frame = gelrig.read_image(d / "press_02.png")
    h = shape.height(frame)
    assert h.dtype == np.float32 and h.shape == (240, 320)
    # press_02: a 31 px contact of the 9.47 mm ball, centred near (88, 111).
    y, x = np.unravel_index(np.argmin(h), h.shape)
    assert abs(x - 88) < 6 and abs(y - 111) < 6, (x, y)
    assert -1.0 < h.min() < -0.35
    stats = shape.stats()
    assert stats["centroid_px"] is not None and stats["contact_area_mm2"] > 5.0
    # The command's map of the same frame, bit for bit.
    gelrig_cli(
        ["shape", str(d / "press_02.png"), "--model", str(shape_file), "--background",
         str(d / "background.png"), "--out", str(tmp_path)]
    )
    assert np.array_equal(np.load(tmp_path / "press_02.height.npy"), h)
    # A strided view (BGR flipped back) reads the same as its contiguous copy.
    bgr = np.ascontiguousarray(frame[..., ::-1])
    assert np.array_equal(shape.height(bgr[..., ::-1]), h)


def test_wrong_frames_are_refused_with_the_fix(shape_file):
    d = ball_dir()
    background = gelrig.read_image(d / "background.png")
    with pytest.raises(gelrig.GelrigError, match="calibrated on 320×240"):
        gelrig.Shape.load(shape_file, background[:100, :100])
    shape = gelrig.Shape.load(shape_file, background, model="lut")
    with pytest.raises(gelrig.GelrigError, match="10×10"):
        shape.height(np.zeros((10, 10, 3), np.uint8))
    with pytest.raises(ValueError, match="height, width, 3"):
        shape.height(np.zeros((240, 320, 4), np.uint8))
    with pytest.raises(gelrig.GelrigError, match="local-linear"):
        gelrig.Shape.load(shape_file, background, model="mlp")
