"""The learned cutout height without torch: the numpy network (nodes/ops/height_net.py)
and its resizes against torch's, the two backends of LearnedHeightPredictor, the
exported .npz against the shipped .pt, and CutoutHeight with torch hidden."""
import json
import os
import pathlib
import subprocess
import sys

import numpy as np
import pytest

from pixgraph_nodes import cutout_height as ch
from pixgraph_nodes.ops import height_net as hn
from pixgraph_nodes.ops import learned_height as lh
from pixgraph_nodes.ops.heightmaps import contact_line_height

torch = pytest.importorskip("torch")
import torch.nn.functional as F  # noqa: E402

sys.path.insert(0, str(pathlib.Path(__file__).parent))
from test_learned_height import DATA, REAL, heldout  # noqa: E402

NPZ = lh.WEIGHTS.with_suffix(".npz")

# The numpy network and torch's compute the same float32 sums in another order (GEMMs
# over up to 3 x 384 x 3 terms, BLAS vs oneDNN): measured differences of the network's
# output (height / bh, values up to ~4) are ~2e-6. 1e-4 leaves room for other BLAS
# kernels and is still 0.05 px at a 512-px box; a wrong layer (the upsampling's
# half-pixel offset, a transposed kernel) is off by > 1e-2 (the sensitivity check below).
NET_TOL = 1e-4


@pytest.fixture(scope="module")
def predictors():
    return (lh.LearnedHeightPredictor(backend="numpy"), lh.LearnedHeightPredictor(backend="torch"))


def _rgba(s):
    return np.concatenate([s["image"], s["alpha"][..., None]], -1).astype(np.float32)


def _inputs():
    """The network inputs (N, 6, 64, 64) of the committed held-out cutouts and their mirrors."""
    xs = []
    for s in heldout(REAL) + heldout(DATA)[:6]:
        colour, alpha = lh.straight_srgb(_rgba(s))
        x, box, _ = lh.prepare(colour, alpha, 64)
        assert box is not None
        xs += [x, x[:, :, ::-1]]
    return np.ascontiguousarray(np.stack(xs))


def test_numpy_network_equals_torchs_on_real_inputs(predictors, monkeypatch):
    num, tor = predictors
    x = _inputs()
    with torch.inference_mode():
        ref = tor.model(torch.from_numpy(x)).numpy()
    got = num.net(x)
    assert got.shape == ref.shape == (len(x), 3, 64, 64) and got.dtype == np.float32
    assert np.abs(ref).max() > 1.0                      # not a trivially small output
    np.testing.assert_allclose(got, ref, rtol=0, atol=NET_TOL)
    # the tolerance tells a wrong layer apart: upsampling by pixel repetition (no half-pixel
    # bilinear) or a kernel mirrored left-right
    monkeypatch.setattr(hn, "upsample2", lambda h, out=None: np.copyto(out, h.repeat(2, 1).repeat(2, 2)) or out)
    assert np.abs(num.net(x) - ref).max() > 100 * NET_TOL
    monkeypatch.undo()
    flipped = hn.HeightNet(*hn.load_npz(NPZ))
    w, b = flipped.down[1][0]
    C = w.shape[0] // 9
    flipped.down[1][0] = (np.ascontiguousarray(w.reshape(3, 3, C, -1)[:, ::-1].reshape(9 * C, -1)), b)
    assert np.abs(flipped(x) - ref).max() > 100 * NET_TOL


def _tol(*sizes):
    # torch computes a source coordinate (i + 0.5) * scale - 0.5 in float32: off by up to
    # ~n * 2^-24 px at output pixel n, times the data's slope (<= 1 for values in [0, 1])
    return 4 * max(sizes) * 2.0 ** -24 + 1e-6


@pytest.mark.parametrize("shape_in,shape_out", [((218, 218), (64, 64)), ((630, 410), (64, 64)),
                                                ((40, 52), (64, 64)), ((64, 64), (218, 218)),
                                                ((64, 64), (40, 40)), ((64, 64), (628, 628)),
                                                ((97, 33), (50, 80))])
@pytest.mark.parametrize("antialias", [True, False])
def test_resize_equals_torchs_interpolate(shape_in, shape_out, antialias):
    a = np.random.default_rng(sum(shape_in)).uniform(0, 1, (3,) + shape_in).astype(np.float32)
    ref = F.interpolate(torch.from_numpy(a)[None], size=shape_out, mode="bilinear", align_corners=False,
                        antialias=antialias)[0].numpy()
    got = hn.resize_chw(a, shape_out, antialias=antialias)
    assert got.shape == ref.shape
    np.testing.assert_allclose(got, ref, rtol=0, atol=_tol(*shape_in, *shape_out))
    if shape_out[0] < shape_in[0] // 2:
        # a shrink with and without antialiasing differ (so the flag is honoured)
        other = hn.resize_chw(a, shape_out, antialias=not antialias)
        assert np.abs(other - ref).max() > 0.05
    assert np.array_equal(lh._resize(a, 64), hn.resize_chw(a, (64, 64), antialias=True))


def test_layers_equal_torchs():
    rng = np.random.default_rng(3)
    x = rng.normal(size=(2, 12, 10, 5)).astype(np.float32)          # (N, H, W, C)
    xt = torch.from_numpy(x).permute(0, 3, 1, 2)
    w = rng.normal(size=(7, 5, 3, 3)).astype(np.float32)
    b = rng.normal(size=7).astype(np.float32)
    ref = F.conv2d(xt, torch.from_numpy(w), torch.from_numpy(b), padding=1).permute(0, 2, 3, 1).numpy()
    np.testing.assert_allclose(hn.conv3x3(x, hn.conv_matrix(w), b), ref, atol=1e-5)
    up = F.interpolate(xt, scale_factor=2, mode="bilinear", align_corners=False).permute(0, 2, 3, 1).numpy()
    np.testing.assert_allclose(hn.upsample2(x), up, atol=1e-6)
    pool = F.max_pool2d(torch.from_numpy(x[:, :, :9]).permute(0, 3, 1, 2), 2).permute(0, 2, 3, 1).numpy()
    assert np.array_equal(hn.max_pool2(x[:, :, :9]), pool)           # an odd width: the last column dropped


def test_npz_is_the_shipped_checkpoint():
    # a retrained .pt without `python -m pixgraph_lab.height.export --npz` fails here
    ck = torch.load(lh.WEIGHTS, map_location="cpu", weights_only=True)
    arrays, cfg = hn.load_npz(NPZ, check_against=lh.WEIGHTS)
    state = {k: v.numpy() for k, v in ck["model"].items() if not k.endswith("num_batches_tracked")}
    assert sorted(arrays) == sorted(state)
    for k, v in state.items():
        assert arrays[k].dtype == v.dtype and np.array_equal(arrays[k], v), k
    assert cfg == json.loads(ck["config"])
    with np.load(NPZ) as z:
        assert str(z["__source_sha256__"]) == hn.pt_digest(lh.WEIGHTS)
    prov = json.loads(lh.WEIGHTS.with_suffix(".json").read_text())["numpy_weights"]
    assert prov["source_sha256"] == hn.pt_digest(lh.WEIGHTS) and prov["bytes"] == NPZ.stat().st_size
    # float16, like the .pt: the two together within the 20 MB for the weights
    assert NPZ.stat().st_size + lh.WEIGHTS.stat().st_size < 20e6


def test_a_stale_npz_is_refused(tmp_path):
    ck = torch.load(lh.WEIGHTS, map_location="cpu", weights_only=True)
    ck["model"]["head.bias"] = ck["model"]["head.bias"] + 1       # "retrained"
    torch.save(ck, tmp_path / "w.pt")
    (tmp_path / "w.npz").write_bytes(NPZ.read_bytes())              # the old export
    with pytest.raises(ValueError, match="export --npz"):
        lh.LearnedHeightPredictor(tmp_path / "w.pt", backend="numpy")
    # the export step writes the matching one
    from pixgraph_lab.height.export import write_numpy_weights
    write_numpy_weights(tmp_path / "w.pt")
    p = lh.LearnedHeightPredictor(tmp_path / "w.pt", backend="numpy")
    assert np.allclose(p.net.head[1], ck["model"]["head.bias"].float().numpy())


def test_choose_backend(tmp_path, monkeypatch):
    monkeypatch.delenv("PIXGRAPH_HEIGHT_BACKEND", raising=False)
    # torch is imported here: on a machine where it sees a GPU it is chosen, else numpy
    gpu = torch.cuda.is_available()
    assert lh.DEFAULT_BACKEND == "numpy" and lh.choose_backend(lh.WEIGHTS) == ("torch" if gpu else "numpy")
    (tmp_path / "run.pt").write_bytes(b"")
    assert lh.choose_backend(tmp_path / "run.pt") == "torch"        # a training run's checkpoint: no .npz
    monkeypatch.setenv("PIXGRAPH_HEIGHT_BACKEND", "torch")
    assert lh.choose_backend(lh.WEIGHTS) == "torch"
    monkeypatch.setenv("PIXGRAPH_HEIGHT_BACKEND", "tensorflow")
    with pytest.raises(ValueError, match="PIXGRAPH_HEIGHT_BACKEND"):
        lh.choose_backend(lh.WEIGHTS)
    with pytest.raises(ValueError, match="backend"):
        lh.choose_backend(lh.WEIGHTS, "jax")
    monkeypatch.delenv("PIXGRAPH_HEIGHT_BACKEND")
    monkeypatch.setitem(sys.modules, "torch", None)                 # torch not importable
    with pytest.raises(FileNotFoundError, match="npz"):
        lh.choose_backend(tmp_path / "run.pt")
    assert lh.choose_backend(lh.WEIGHTS) == "numpy"


def _large(s, k=7):
    """A held-out cutout enlarged k x (nearest), so its crop is past the 512-px work size."""
    return np.repeat(np.repeat(_rgba(s), k, 0), k, 1)


def test_backends_agree_on_predict_full(predictors):
    num, tor = predictors
    cases = [_rgba(s) for s in heldout(REAL)] + [_large(heldout(REAL)[0])]
    for rgba in cases:
        for contact in ("ground", "free"):
            a, b = num.predict_full(rgba, contact=contact), tor.predict_full(rgba, contact=contact)
            m = rgba[..., 3] > 0.5
            assert np.abs(a["height"]).max() > 1.0
            # heights [px]: the network's 1e-4 (x bh) through paste, pin and foot snap
            np.testing.assert_allclose(a["height"], b["height"], rtol=0, atol=1e-3)
            np.testing.assert_allclose(a["auto_height"], b["auto_height"], rtol=0, atol=1e-3)
            assert np.array_equal(a["heuristic"], b["heuristic"])
            assert abs(a["signal"] - b["signal"]) < 1e-4 and a["confidence"] == b["confidence"]
            assert a["use_learned"] == b["use_learned"] and a.get("work_scale") == b.get("work_scale")
            for k in ("est_mae_learned", "est_mae_heuristic"):
                assert abs(a[k] - b[k]) < 1e-3 * max(1.0, abs(b[k])), k
            assert np.all(a["height"][~m] == 0)
    assert cases[-1].shape[0] > 512 and "work_scale" in num.predict_full(cases[-1])


_NO_TORCH = r"""
import importlib.abc, sys
class Block(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name == "torch" or name.startswith("torch."):
            raise ImportError("torch is hidden by the test")
sys.meta_path.insert(0, Block())
import numpy as np
from pixgraph.node import Namespace
from pixgraph_nodes import cutout_height as ch
class Ctx:
    device = graph_dir = None
    def __init__(self):
        self.logs = []
    def log(self, m):
        self.logs.append(m)
z = np.load(sys.argv[1])
out = {}
for method in ("learned", "auto"):
    ctx = Ctx()
    params = Namespace(ch.CutoutHeight.spec.coerce_params({"method": method}))
    r = ch.CutoutHeight().compute(ctx, Namespace({"mask": z["alpha"], "image": z["image"]}), params)
    out[method], out[method + "_log"] = r["height"], np.array(ctx.logs[0])
out["backend"] = np.array(ch.learned_predictor().backend)
out["torch_loaded"] = np.array(sys.modules.get("torch") is not None)
np.savez(sys.argv[2], **out)
"""


@pytest.mark.parametrize("index", [0, 3])
def test_cutout_height_without_torch_gives_torchs_map(tmp_path, index):
    s = heldout(REAL)[index]
    np.savez(tmp_path / "in.npz", image=s["image"], alpha=s["alpha"])
    env = dict(os.environ, PIXGRAPH_HEIGHT_BACKEND="")
    run = subprocess.run([sys.executable, "-c", _NO_TORCH, str(tmp_path / "in.npz"), str(tmp_path / "o.npz")],
                         env=env, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    z = np.load(tmp_path / "o.npz")
    assert str(z["backend"]) == "numpy" and not bool(z["torch_loaded"])
    ref = lh.LearnedHeightPredictor(backend="torch").predict_full(ch.cutout_rgba(s["alpha"], s["image"]))
    m = s["alpha"] > 0.5
    assert str(z["learned_log"]).startswith("learned: learned height")
    np.testing.assert_allclose(z["learned"], ref["height"], rtol=0, atol=1e-3)
    assert np.abs(z["learned"] - contact_line_height(s["alpha"]))[m].max() > 1.0   # not the fallback
    if ref["use_learned"]:
        np.testing.assert_allclose(z["auto"], ref["height"], rtol=0, atol=1e-3)
    else:
        assert str(z["auto_log"]).startswith("auto: contact line")


def test_blas_threads_sets_and_restores():
    calls = hn._openblas_calls()
    if calls is None:
        pytest.skip("numpy's BLAS is not a bundled OpenBLAS")
    set_, get = calls
    before = get()
    set_(2)
    try:
        with hn.blas_threads(1):
            assert get() == 1
            with hn.blas_threads(1):
                assert get() == 1
            assert get() == 1                       # the inner block leaves the outer one's setting
        assert get() == 2
    finally:
        set_(before)


@pytest.mark.parametrize("content", [NPZ.read_bytes()[:100000],                   # cut short (a failed copy)
                                     b"",                                          # empty
                                     b"version https://git-lfs.github.com/spec/v1\noid sha256:ab\nsize 3966802\n",
                                     b"\x93NUMPY not an npz"])
def test_a_broken_npz_is_an_error_naming_the_file(tmp_path, content):
    # numpy's own errors ("File is not a zip file", "No data left in file", "This file contains
    # pickled (object) data ... allow_pickle") name no file and, for the last, suggest unpickling
    (tmp_path / "w.npz").write_bytes(content)
    with pytest.raises(ValueError, match=r"w\.npz.*export --npz") as e:
        lh.LearnedHeightPredictor(tmp_path / "w.npz", backend="numpy")
    assert "allow_pickle" not in str(e.value)


def test_an_npz_of_another_network_is_an_error_naming_the_file(tmp_path):
    arrays, cfg = hn.load_npz(NPZ)
    del arrays["head.weight"]
    hn.write_npz(arrays, cfg, tmp_path / "w.npz")
    with pytest.raises(ValueError, match=r"w\.npz.*head\.weight"):
        lh.LearnedHeightPredictor(tmp_path / "w.npz", backend="numpy")


def test_blas_threads_through_threadpoolctl_restores_after_overlapping_threads(monkeypatch):
    # numpy's BLAS not a bundled OpenBLAS (Debian's numpy, MKL): threadpoolctl sets the limit.
    # Two predictions on the engine's threads overlap: A enters, B enters, A leaves, B leaves.
    # Each threadpool_limits restores what it saw on entry, so B (which saw A's 1) left the
    # whole process at 1 BLAS thread for good. A stand-in threadpoolctl records the setting.
    import threading
    import types
    blas = {"threads": 4}

    class Limits:
        def __init__(self, limits, user_api):
            self.n = limits

        def __enter__(self):
            self.before = blas["threads"]
            blas["threads"] = self.n

        def __exit__(self, *exc):
            blas["threads"] = self.before

    monkeypatch.setitem(sys.modules, "threadpoolctl", types.SimpleNamespace(threadpool_limits=Limits))
    monkeypatch.setattr(hn, "_openblas_calls", lambda: None)
    a_in, b_in, a_out = threading.Event(), threading.Event(), threading.Event()
    seen = {}

    def a():
        with hn.blas_threads(1):
            a_in.set()
            b_in.wait(5)
            seen["a"] = blas["threads"]
        a_out.set()

    def b():
        a_in.wait(5)
        with hn.blas_threads(1):
            b_in.set()
            a_out.wait(5)
            seen["b"] = blas["threads"]              # still inside: still limited

    ts = [threading.Thread(target=a), threading.Thread(target=b)]
    [t.start() for t in ts]
    [t.join(10) for t in ts]
    assert seen == {"a": 1, "b": 1}
    assert blas["threads"] == 4                      # the count from before the first block
