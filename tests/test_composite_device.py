"""The composite's OpenCL kernels (ops/composite.cl) against the numpy reference
(``composite_layers``): the same numbers, bit for bit, on random and edge inputs
(coverage exactly 0 and 1 and outside [0, 1], boxes of sizes that are no multiple
of the work-group, the whole image, one pixel, grey and RGBA backgrounds), and
which device the Composite nodes pick."""
import numpy as np
import pytest

from pixgraph.node import Namespace
from pixgraph_nodes import composite as composite_node
from pixgraph_nodes import reflection_composite as reflection_node
from pixgraph_nodes.ops import composite as C
from pixgraph_nodes.ops.composite import composite_layers, composite_layers_cl

TINT = (0.1, 0.2, 0.3)


def _scene(rng, H, W, channels, fg_channels, shadow_box, fg_box, refl_box):
    bg = rng.random((H, W, channels), dtype=np.float32)
    dark = np.zeros((H, W), np.float32)
    r0, r1, c0, c1 = shadow_box
    dark[r0:r1, c0:c1] = rng.random((r1 - r0, c1 - c0), dtype=np.float32) * 1.4 - 0.2    # out of [0, 1] too
    a = np.zeros((H, W), np.float32)
    fg = np.zeros((H, W, fg_channels), np.float32)
    r0, r1, c0, c1 = fg_box
    a[r0:r1, c0:c1] = rng.choice(np.float32([0.0, 1.0, 0.25, 1.2, -0.1, 0.7]), (r1 - r0, c1 - c0))
    fg[r0:r1, c0:c1] = rng.random((r1 - r0, c1 - c0, fg_channels), dtype=np.float32) * np.clip(a, 0, 1)[r0:r1, c0:c1, None]
    refl = np.zeros((H, W, 4), np.float32)
    r0, r1, c0, c1 = refl_box
    refl[r0:r1, c0:c1, 3] = rng.random((r1 - r0, c1 - c0), dtype=np.float32)
    refl[r0:r1, c0:c1, :3] = refl[r0:r1, c0:c1, 3:] * rng.random((r1 - r0, c1 - c0, 3), dtype=np.float32)
    return bg, dark, [(refl, refl[..., 3]), (fg, a)]


@pytest.mark.parametrize("channels", [1, 2, 3, 4])
@pytest.mark.parametrize("fg_channels", [1, 2, 3, 4])
def test_kernels_equal_numpy_on_random_layers(device, channels, fg_channels):
    rng = np.random.default_rng(10 * channels + fg_channels)
    H, W = 53, 71                                     # no multiple of the 16 x 16 work-group
    bg, dark, layers = _scene(rng, H, W, channels, fg_channels, (3, 40, 5, 61), (17, 52, 30, 69), (30, 53, 0, 67))
    keep = [x.copy() for x in (bg, dark, *layers[0], *layers[1])]
    want = composite_layers(bg, dark, 0.8, TINT, layers)
    got = composite_layers_cl(device, bg, dark, 0.8, TINT, layers)
    assert got.dtype == np.float32 and got.shape == bg.shape
    np.testing.assert_array_equal(got, want)
    for x, k in zip((bg, dark, *layers[0], *layers[1]), keep):
        np.testing.assert_array_equal(x, k)           # inputs untouched


@pytest.mark.parametrize("case", ["whole image", "one pixel", "nothing touched", "only a shadow", "only a layer"])
def test_kernels_equal_numpy_on_edge_boxes(device, case):
    rng = np.random.default_rng(7)
    H, W = 33, 17
    full = (0, H, 0, W)
    boxes = {"whole image": (full, full, full), "one pixel": ((5, 6, 9, 10), (32, 33, 16, 17), (0, 1, 0, 1)),
             "nothing touched": ((0, 0, 0, 0),) * 3, "only a shadow": ((1, 30, 2, 15), (0, 0, 0, 0), (0, 0, 0, 0)),
             "only a layer": ((0, 0, 0, 0), (4, 20, 3, 12), (0, 0, 0, 0))}[case]
    bg, dark, layers = _scene(rng, H, W, 4, 4, *boxes)
    if case == "whole image":
        layers[1][1][:] = 1.0                             # full coverage: the cutout alone
        layers[1][0][:] = rng.random((H, W, 4), dtype=np.float32)
    want = composite_layers(bg, dark, 1.0, (0.0, 0.5, 1.0), layers)
    got = composite_layers_cl(device, bg, dark, 1.0, (0.0, 0.5, 1.0), layers)
    np.testing.assert_array_equal(got, want)
    if case == "nothing touched":
        np.testing.assert_array_equal(got, bg)
    if case == "whole image":
        np.testing.assert_array_equal(got[..., :3], layers[1][0][..., :3])


def test_kernels_on_views_and_without_shadow(device):
    """A background that is a view (not contiguous), no shadow, one layer whose
    coverage is its own channel and one whose coverage is a separate array."""
    rng = np.random.default_rng(2)
    big = rng.random((40, 90, 3), dtype=np.float32)
    bg = big[:, 5:80]
    _, _, layers = _scene(rng, 40, 75, 3, 4, (0, 0, 0, 0), (10, 39, 7, 60), (20, 40, 1, 74))
    assert C._channel_of(layers[0][1], layers[0][0]) == 3 and C._channel_of(layers[1][1], layers[1][0]) is None
    np.testing.assert_array_equal(composite_layers_cl(device, bg, None, 0.5, TINT, layers),
                                  composite_layers(bg, None, 0.5, TINT, layers))


def test_boxes_hold_every_touched_pixel():
    """The cutout's box: its coverage's and every channel's nonzero pixels, from its
    own alpha channel when the coverage is that channel."""
    fg = np.zeros((20, 30, 4), np.float32)
    a = np.zeros((20, 30), np.float32)
    fg[3, 4, 1] = 0.5                 # colour without coverage
    a[15, 20] = 0.2                   # coverage without colour
    assert C._over_plan((20, 30, 3), fg, a)[2] == (3, 16, 4, 21)
    fg[18, 27, 3] = 0.1
    assert C._over_plan((20, 30, 3), fg, fg[..., 3])[2] == (3, 19, 4, 28)
    assert C._over_plan((20, 30, 3), np.zeros_like(fg), np.zeros_like(a)) is None


def test_channel_of_only_where_the_coverage_is_that_channel():
    """``_channel_of`` reads the coverage's address: a channel of the same memory, seen
    through the same strides, and no other (views with negative or skipping strides,
    copies); where it is wrong the cutout's box would miss coverage."""
    X = np.zeros((12, 10, 4), np.float32)
    assert C._channel_of(X[..., 3], X) == 3
    R = X[::-1, ::-1]                                  # negative row and column strides
    assert C._channel_of(R[..., 3], R) == 3 and C._channel_of(X[..., 3], R) is None
    S = X[..., ::2]                                    # channels 0 and 2: X's channel 1 lies between
    assert C._channel_of(X[..., 1], S) is None
    assert C._channel_of(X[..., 3], X[..., :3]) is None     # past the view's channels
    assert C._channel_of(X[..., 3].copy(), X) is None
    assert C._channel_of(X[::2, :, 3], X[:6]) is None            # every other row: the same start, other rows
    X[5, 6, 1] = 0.8                                   # coverage only in the channel S skips
    assert C._over_plan((12, 10, 3), S, X[..., 1])[2] == (5, 6, 6, 7)
    bg = np.full((12, 10, 3), 0.5, np.float32)
    np.testing.assert_array_equal(composite_layers(bg, layers=[(S, X[..., 1])])[5, 6],
                                  np.float32(0.5) * (np.float32(1.0) - np.float32(0.8)))       # bg (1 - a) + 0


class _Fake:
    """A device whose OpenCL type is ``kind``."""
    def __init__(self, kind):
        import types
        self.queue = types.SimpleNamespace(device=types.SimpleNamespace(type=kind))


def test_device_for_full_size_on_a_gpu_only(device):
    import pyopencl as cl

    opened = []

    def never():            # device_for turns any exception into numpy: record the call instead
        opened.append(True)
        return _Fake(cl.device_type.GPU)
    assert C.device_for((512, 384, 3), never) is None
    assert C.device_for((1999, 2001, 3), never) is None           # 3,999,999 pixels: still the host
    assert opened == [], "a small image must not open the device"
    big = (2000, 2000, 3)
    gpu = _Fake(cl.device_type.GPU)
    assert C.device_for(big, lambda: gpu) is gpu
    assert C.device_for(big, lambda: _Fake(cl.device_type.CPU)) is None
    assert C.device_for(big, lambda: device) is (None if device.queue.device.type & cl.device_type.CPU else device)

    def no_platform():
        raise RuntimeError("no OpenCL platform")
    # a composite needs no device: numpy where none opens
    assert C.device_for(big, no_platform) is None


@pytest.mark.parametrize("node", ["composite", "reflection"])
def test_nodes_on_the_device_give_the_numpy_image(device, monkeypatch, node):
    rng = np.random.default_rng(5)
    bg, dark, layers = _scene(rng, 45, 60, 3, 4, (2, 30, 3, 50), (10, 44, 20, 58), (25, 45, 0, 60))
    refl, (fg, a) = layers[0][0], layers[1]
    inputs = {"background": bg, "cutout": fg, "alpha": a, "shadow": dark}
    if node == "reflection":
        cls, module = reflection_node.ReflectionComposite, reflection_node
        inputs.update(reflection=refl, refraction=None)
        want = composite_layers(bg, dark, 0.6, TINT, layers)
    else:
        cls, module = composite_node.Composite, composite_node
        want = composite_layers(bg, dark, 0.6, TINT, layers[1:])
    params = Namespace(cls.spec.coerce_params({"opacity": 0.6, "tint": list(TINT)}))
    used = []

    def on_device(shape, open_device):
        used.append(open_device())
        return used[-1]
    monkeypatch.setattr(module, "device_for", on_device)

    class Ctx:
        pass
    ctx = Ctx()
    ctx.device = device
    got = cls().compute(ctx, Namespace(inputs), params)["image"]
    assert used == [device]
    np.testing.assert_array_equal(got, want)
