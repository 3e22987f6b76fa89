"""The server's PNG encoding: banded conversion gives the same bytes as converting the
whole image at once, and the sRGB values are the standard ones."""
import io

import numpy as np
import pytest
from PIL import Image

import pixgraph_serve.encode as E


@pytest.mark.parametrize("shape", [(300, 200, 4), (301, 203, 3), (97, 55), (64, 64, 1), (50, 70, 2)])
@pytest.mark.parametrize("scale", [1, 2, 3])
def test_bands_give_the_whole_image(monkeypatch, shape, scale):
    x = np.random.default_rng(1).random(shape, dtype=np.float32) * 1.2 - 0.1
    whole = E._to_u8(E.downscale(x, scale))
    monkeypatch.setattr(E, "BAND_VALUES", 500)          # many bands of a few rows
    got = np.asarray(Image.open(io.BytesIO(E.encode_png(x, "x", scale))))
    assert got.shape == whole.shape and np.array_equal(got, whole)


def test_srgb_values_and_straight_alpha():
    x = np.zeros((2, 2, 4), np.float32)
    x[0, 0] = [0.25, 0.75, 0.0031308, 1.0]
    x[0, 1] = [0.125, 0.0, 0.0, 0.5]                     # premultiplied: colour 0.25 at half coverage
    got = np.asarray(Image.open(io.BytesIO(E.encode_png(x))))
    assert got[0, 0].tolist() == [137, 225, 10, 255]       # 255 * (1.055 v^(1/2.4) - 0.055), 12.92 v
    assert got[0, 1].tolist() == [137, 0, 0, 128]
    assert got[1, 1].tolist() == [0, 0, 0, 0]
