"""The light's softness, as SSN++'s training data and ``pixgraph.Shadow``'s method
table define it (no torch: ``ops.ssn`` re-exports it)."""
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
