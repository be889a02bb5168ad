"""PNG output without an imaging package: read back with Pillow, values and orientation."""

import numpy as np
import pytest
from PIL import Image
from vplace import images


def test_png_round_trip(tmp_path):
    rgb = np.random.default_rng(0).integers(0, 256, size=(5, 7, 3), dtype=np.uint8)
    path = images.write_png_rgb8(tmp_path / "a.png", rgb)
    assert np.array_equal(np.asarray(Image.open(path).convert("RGB")), rgb)
    with pytest.raises(ValueError, match="uint8"):
        images.write_png_rgb8(tmp_path / "b.png", rgb.astype(np.float32))


def test_srgb_transfer_round_trip_and_clamp(tmp_path):
    x = np.linspace(0, 1, 101)
    np.testing.assert_allclose(images.srgb_to_linear(images.linear_to_srgb(x)), x, atol=1e-12)
    img = np.zeros((2, 2, 3), np.float32)
    img[0, 0] = 5.0  # clamped to white; row 0 stays at the top
    got = np.asarray(Image.open(images.save_png(tmp_path / "c.png", img)))
    assert got[0, 0].tolist() == [255, 255, 255] and got[1, 1].tolist() == [0, 0, 0]
