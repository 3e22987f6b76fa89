"""Model no more than a scene needs: the cheapest shadow method expected to meet
an accuracy target, from a table measured on the ground-truth benchmarks.

The table (``weights/shadow_methods.json``, written by
``python -m pixgraph_lab.auto_table``) holds, for each receiver kind (``wall``,
``ground``) and light-softness bin (radius / distance, ``ssn.softness_of``),
and each method (``hard``: one hard shadow; ``soft:N``: the classical soft
shadow with N light samples; ``ssn``: SSN++), the per-sample RMSE against the
Mitsuba ground truth -- its mean and its 90th percentile -- and each method's
median time at 256^2.

:func:`choose` picks, among the methods whose 90th-percentile RMSE in the
scene's cell is at most ``max_rmse`` (so that on the benchmark it exceeded the
target on at most 10 % of the cell's samples), the one with the least expected
time at the image's size; if none qualifies, the one with the lowest mean
RMSE (``met = False``). Resolution enters only through time:
the benchmark's errors are measured at 256^2, and large images run SSN++ on a
window at its trained scale and the classical shadows on a proxy
(``upsample``), so their errors are taken to carry over (docs/auto.md).

:func:`scene_features` measures what the table is indexed by, the same way for
the table's samples and for the node's inputs.
"""
from __future__ import annotations

import dataclasses
import functools
import json
import pathlib

import numpy as np

TABLE = pathlib.Path(__file__).resolve().parents[1] / "weights" / "shadow_methods.json"
#: a background pixel higher than this [px] above its ground point is a wall
WALL_HEIGHT_PX = 0.5
#: the scene's receiver is "wall" when at least this fraction of the hard shadow falls on walls
WALL_FRACTION = 0.1
#: a cell with fewer samples than this falls back to its receiver's pooled row
MIN_CELL = 5
#: the percentile of per-sample RMSE that must meet the target
PERCENTILE = 90


def receiver_kind(shadowed: np.ndarray, mask: np.ndarray, bg_height: np.ndarray) -> str:
    """``"wall"`` if >= WALL_FRACTION of the shadowed background pixels have a
    background pixel height above WALL_HEIGHT_PX, else ``"ground"``."""
    recv = np.asarray(shadowed, bool) & ~(np.asarray(mask) > 0.5)
    n = int(recv.sum())
    if n == 0:
        return "ground"
    wall = np.nan_to_num(np.asarray(bg_height, np.float32))[recv] > WALL_HEIGHT_PX
    return "wall" if wall.mean() >= WALL_FRACTION else "ground"


def scene_features(device, mask, fg_height, bg_height, light, camera, thickness=1.0):
    """(softness, receiver, lit) of a scene: the light's softness
    (``softness.softness_of``), the receiver kind of its hard shadow (from the light's
    centre, traced at a proxy of at most 512 px) and that hard shadow's lit map
    at the proxy's size (reused when the choice is ``hard`` and no proxy was needed)."""
    from .lights import light_point
    from .resample import Window
    from .shadow import hard_shadow
    mask = np.asarray(mask)
    from .softness import softness_of
    softness = softness_of(light, camera, mask, fg_height)
    H, W = mask.shape
    win = Window.whole(H, W, 512)
    m, fg, bg = win.scene(mask, fg_height, bg_height)
    lit = hard_shadow(device, m, fg, bg, win.light_points(light_point(light, camera)), thickness * win.ky)
    return softness, receiver_kind(lit < 0.5, m, bg), lit


@functools.lru_cache(maxsize=4)
def _load(path: str, mtime_ns: int) -> dict:
    return json.loads(pathlib.Path(path).read_text())


def load_table(path=TABLE) -> dict:
    path = pathlib.Path(path)
    if not path.exists():
        raise FileNotFoundError(f"no shadow method table {path} (python -m pixgraph_lab.auto_table writes it)")
    return _load(str(path), path.stat().st_mtime_ns)


def table_digest(path=TABLE) -> str:
    """First 12 hex digits of the table file's sha256 ("none" if absent): part of the
    Shadow node's impl_version, so regenerating the table invalidates cached choices."""
    import hashlib
    try:
        return hashlib.sha256(pathlib.Path(path).read_bytes()).hexdigest()[:12]
    except OSError:
        return "none"


def cost_ms(table: dict, method: str, pixels: int) -> float:
    """Expected ms of ``method`` on an image of ``pixels`` pixels: the table's median
    at 256^2, scaled by the pixels traced (classical methods: the image, capped at
    the proxy's ``AUTO_MAX_SIDE``^2; SSN++: its window, at least 256^2)."""
    from .upsample import AUTO_MAX_SIDE
    base = float(table["ms_256"][method])
    ref = 256 * 256
    if method == "ssn":
        return base
    return base * min(pixels, AUTO_MAX_SIDE * AUTO_MAX_SIDE) / ref


@dataclasses.dataclass(frozen=True)
class Choice:
    method: str
    met: bool
    expected_p90: float
    expected_mean: float
    ms: float
    cell: str
    reason: str


def cell_of(table: dict, softness: float, receiver: str) -> tuple[str, dict]:
    """The table's cell (name, {method: stats}) for a scene; a thin cell falls back to
    the receiver's pooled row."""
    edges = table["softness_edges"]
    b = int(np.clip(np.searchsorted(edges, softness, side="right") - 1, 0, len(edges) - 2))
    rec = table["cells"][receiver]
    span = f"{edges[b]:g}-{edges[b + 1]:g}" if edges[b + 1] < 1.0 else f">= {edges[b]:g}"
    name = f"{receiver}, softness {span}"
    cell = rec["bins"][b]
    if min(st["n"] for st in cell.values()) < MIN_CELL:
        return f"{receiver}, all softness (bin {span} has too few samples)", rec["all"]
    return name, cell


def choose(table: dict, softness: float, receiver: str, pixels: int, max_rmse: float,
           methods=None) -> Choice:
    """The cheapest method expected to meet ``max_rmse`` (see the module docstring)."""
    name, cell = cell_of(table, softness, receiver)
    cands = [m for m in (methods or table["methods"]) if m in cell]
    if not cands:
        raise ValueError(f"no method of {methods} in the shadow method table")
    key = f"p{PERCENTILE}"
    ok = [m for m in cands if cell[m][key] <= max_rmse]
    if ok:
        m = min(ok, key=lambda x: (cost_ms(table, x, pixels), cell[x][key]))
        why = (f"cheapest whose {key} RMSE {cell[m][key]:.3f} <= {max_rmse:g} in cell [{name}]"
               f" ({len(ok)} of {len(cands)} qualify)")
    else:   # the most accurate on average (a mean of 10-40 samples is steadier than their p90)
        m = min(cands, key=lambda x: cell[x]["mean"])
        why = (f"no method's {key} RMSE <= {max_rmse:g} in cell [{name}]: the most accurate on average "
               f"(mean {cell[m]['mean']:.3f}, {key} {cell[m][key]:.3f})")
    return Choice(m, bool(ok), float(cell[m][key]), float(cell[m]["mean"]), cost_ms(table, m, pixels), name,
                  why)
