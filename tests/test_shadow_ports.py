"""The shadow-family nodes share one declaration of their five inputs, their
``thickness`` param and their input check (nodes/_shadow_ports.py)."""
import numpy as np
import pytest

from pixgraph.errors import InputError
from pixgraph.node import Namespace
from pixgraph.registry import Registry
from pixgraph_nodes.ops.camera import Camera
from pixgraph_nodes.ops.lights import point_light

FAMILY = ["pixgraph.HardShadow", "pixgraph.SoftShadow", "pixgraph.SoftShadowSSN", "pixgraph.Shadow",
          "pixgraph.BufferChannels"]
REG = Registry.discover()


def test_one_declaration_of_the_five_inputs_and_thickness():
    specs = [REG.get(t) for t in FAMILY]
    ports = {tuple((p.name, p.type, p.optional) for p in s.inputs) for s in specs}
    assert len(ports) == 1
    (only,) = ports
    assert [n for n, _, _ in only] == ["mask", "fg_height", "bg_height", "light", "camera"]
    thick = {s.type_id: (p.kind, p.default, p.min, p.max, p.unit) for s in specs for p in s.params
             if p.name == "thickness"}
    # in image pixels (a scaled run scales them), but SSN++'s, in its window's (which do not scale)
    assert thick == {t: ("float", 1.0, 0.0, 1000.0, "window px" if t == "pixgraph.SoftShadowSSN" else "px")
                     for t in FAMILY}
    # the shared block's docs, where a node does not restate a port
    assert REG.get("pixgraph.HardShadow").input("light").doc == "the light"
    assert REG.get("pixgraph.SoftShadow").input("light").doc.startswith("the light; its radius")


class _Ctx:
    node_id = "n"

    def __getattr__(self, name):  # the check must come before any device, progress or log use
        raise AssertionError(f"ctx.{name} used before the inputs were checked")


@pytest.mark.parametrize("type_id", FAMILY)
def test_every_member_checks_its_inputs_the_same_way(type_id):
    spec = REG.get(type_id)
    cam = Camera(width=8, height=6, hfov=50.0, horizon=1.0, cam_height=1.0)
    light = point_light((0.0, 3.0, 2.0))
    good = np.zeros((6, 8), np.float32)
    params = Namespace(spec.coerce_params({}))
    bad_size = Namespace(dict(mask=np.zeros((5, 8), np.float32), fg_height=good, bg_height=good, light=light,
                              camera=cam))
    with pytest.raises(InputError, match=r"inputs must have the same size \(width x height\): "
                                         r"mask 8x5, fg_height 8x6, bg_height 8x6, camera 8x6"):
        spec.cls().compute(_Ctx(), bad_size, params)
    neg = good.copy()
    neg[2, 3] = -1.0
    bad_height = Namespace(dict(mask=good, fg_height=good, bg_height=neg, light=light, camera=cam))
    with pytest.raises(InputError, match=r"input 'bg_height': 1 pixel height\(s\) not finite or negative "
                                         r"\(first: negative at pixel u=3, v=2\)"):
        spec.cls().compute(_Ctx(), bad_height, params)


def test_a_scaled_run_scales_thickness_in_image_px_and_keys_the_nodes_that_undo_it():
    """At a quarter of the resolution the engine hands every image-px thickness over
    quartered, SoftShadowSSN's (window px) as it is; the two nodes that divide the scale
    back out for SSN++ (Shadow with method ssn, PreviewShadow with method ssn) declare
    uses_scale, so their results are keyed by the scale, and no other member does."""
    from pixgraph.resolve import scale_params
    got = {}
    for t in FAMILY + ["pixgraph.PreviewShadow"]:
        params, key = {"thickness": 4.0}, {"thickness": 4.0}
        scale_params(REG.get(t), params, key, 0.25)
        assert key["thickness"] == params["thickness"]
        got[t] = (params["thickness"], key.get("@scale"))
    assert got == {"pixgraph.HardShadow": (1.0, None), "pixgraph.SoftShadow": (1.0, None),
                   "pixgraph.SoftShadowSSN": (4.0, None), "pixgraph.Shadow": (1.0, 0.25),
                   "pixgraph.BufferChannels": (1.0, None), "pixgraph.PreviewShadow": (1.0, 0.25)}
