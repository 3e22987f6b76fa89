"""The light's softness, as SSN++'s training data and ``pixgraph.Shadow``'s method
table define it (no torch: ``ops.ssn`` re-exports it), and the scale of SSN++'s
window (``ssn_crop`` re-exports it; ``pixgraph.PreviewShadow`` reads SSN++'s
thickness with it)."""
from __future__ import annotations

import numpy as np


def softness_of(light, camera, mask: np.ndarray, fg_height: np.ndarray) -> float:
    """The light's softness as the training data defines it: disk radius over the
    distance from the light's centre to the object's centre (dimensionless).

    The object's centre is the mean of the cutout's reconstructed 3D points
    (``camera.back_project``); a directional light's softness is the tangent of
    its angular radius. Point lights have softness 0.
    """
    if light.kind == "directional":
        return float(np.tan(light.angular_radius))
    if light.radius <= 0.0:
        return 0.0
    inside = np.asarray(mask) > 0.5
    u, v = camera.pixel_grid()
    P, valid = camera.back_project(u[inside], v[inside], np.asarray(fg_height, np.float64)[inside])
    if not valid.any():
        raise ValueError("the cutout has no pixel below the horizon: cannot place it in 3D")
    centre = P[valid].mean(axis=0)
    return float(light.radius / max(np.linalg.norm(np.asarray(light.position) - centre), 1e-9))


#: cutout height [network px] SSN++'s window keeps: the training objects' range
#: (docs/ground-truth.md; ``ssn_crop.choose_window``)
OBJECT_PX = (64.0, 120.0)


def network_scale(object_px: float) -> float:
    """Scale from image to network px that puts a cutout ``object_px`` tall in OBJECT_PX."""
    lo, hi = OBJECT_PX
    return hi / object_px if object_px > hi else (lo / max(object_px, 1.0) if object_px < lo else 1.0)


def window_scale(mask: np.ndarray) -> float:
    """The scale [network px per image px] SSN++'s window starts from for this cutout
    (``ssn_crop.render``): :func:`network_scale` of the mask's height in rows (mask >
    0.5). ``ssn_crop.choose_window`` shrinks it further when the shadow's extent
    passes ``MAX_SIDE`` network px (and rounds the window to whole pixels), which
    needs the shadow; 1.0 for an empty mask."""
    rows = np.flatnonzero((np.asarray(mask) > 0.5).any(axis=1))
    return network_scale(float(rows[-1] - rows[0] + 1)) if rows.size else 1.0
