"""Reflection receivers: a wall template must not mirror the cutout when only the floor
reflects (receivers: ground, or a receiver mask)."""
import numpy as np
import pytest

from pixgraph.session import Session
from pixgraph_nodes.ops.heightmaps import back_wall, contact_line_height


@pytest.fixture(scope="module")
def session(device):
    return Session(device=device, disk_cache=None)


def _run(session, receiver=None, **params):
    H = W = 96
    a = np.zeros((H, W), np.float32)
    a[40:80, 40:56] = 1.0                             # a box standing at row 80, in front of the wall
    cut = np.concatenate([a[:, :, None] * np.array([0.8, 0.3, 0.1], np.float32), a[:, :, None]], axis=2)
    wall = back_wall(W, H, row=60.0)                  # the wall meets the floor at row 60
    b = session.builder()
    b.add("pixgraph.Camera", "cam", width=W, height=H, hfov=50, horizon=20)
    b.add("pixgraph.InputImage", "cut")
    b.add("pixgraph.InputPixelHeight", "fg")
    b.add("pixgraph.InputPixelHeight", "bg")
    b.add("pixgraph.Reflection", "refl", roughness=0.1, min_spp=8, max_spp=8, **params)
    for src, dst in [("cam.camera", "camera"), ("cut.image", "cutout"), ("fg.height", "fg_height"),
                     ("bg.height", "bg_height")]:
        b.connect(src, f"refl.{dst}")
    bind = {"cut": cut, "fg": contact_line_height(a), "bg": wall}
    if receiver is not None:
        b.add("pixgraph.InputMask", "recv")
        b.connect("recv.mask", "refl.receiver")
        bind["recv"] = receiver
    b.output("layer", "refl.layer")
    return session.run(b.build(), bind=bind)["layer"], wall, a


def test_ground_receivers_keep_the_wall_clean(session):
    everywhere, wall, a = _run(session)
    floor_only, _, _ = _run(session, receivers="ground")
    on_wall = (wall > 0.5) & (a == 0)
    on_floor = (wall <= 0.5) & (a == 0)
    # the wall does mirror the box when every surface reflects...
    assert everywhere[..., 3][on_wall].sum() > 1.0
    # ...and not at all when only the floor does; the floor's reflection is unchanged
    assert floor_only[..., 3][on_wall].max() == 0.0
    np.testing.assert_array_equal(floor_only[on_floor], everywhere[on_floor])
    assert floor_only[..., 3][on_floor].sum() > 5.0


def test_receiver_mask_limits_the_reflection(session):
    everywhere, wall, a = _run(session)
    recv = np.zeros(wall.shape, np.float32)
    recv[85:] = 1.0                                    # only a strip near the camera reflects
    strip, _, _ = _run(session, receiver=recv)
    assert strip[:85].max() == 0.0
    np.testing.assert_array_equal(strip[85:], everywhere[85:])
    assert strip[85:, :, 3].sum() > 1.0
