"""Banded work on the machine's cores (nodes/ops/bands.py): every band once, errors
re-raised after all bands stop, no pool inside the pool, and the banded operations
give the same numbers on one thread and on several."""
import threading

import numpy as np
import pytest

from pixgraph_nodes.ops import bands


def test_every_band_once_and_in_parallel_threads(monkeypatch):
    monkeypatch.setenv("PIXGRAPH_THREADS", "3")
    seen, names = [], set()
    lock = threading.Lock()

    def fn(r0, r1):
        with lock:
            seen.append((r0, r1))
            names.add(threading.current_thread().name)
    bands.for_bands(fn, 5, 1000, 64)
    assert sorted(seen) == [(r, min(1000, r + 64)) for r in range(5, 1000, 64)]
    assert all(n.startswith("pixgraph-band") for n in names)


def test_one_thread_runs_in_the_caller_in_order(monkeypatch):
    monkeypatch.setenv("PIXGRAPH_THREADS", "1")
    seen = []
    bands.for_bands(lambda r0, r1: seen.append((r0, threading.current_thread() is threading.main_thread())),
                    0, 10, 3)
    assert seen == [(0, True), (3, True), (6, True), (9, True)]
    monkeypatch.setenv("PIXGRAPH_THREADS", "two")
    with pytest.raises(ValueError, match="PIXGRAPH_THREADS"):
        bands.for_bands(lambda r0, r1: None, 0, 10, 3)


def test_an_error_is_raised_after_every_band_has_stopped(monkeypatch):
    monkeypatch.setenv("PIXGRAPH_THREADS", "2")
    done = []

    def fn(r0, r1):
        if r0 == 0:
            raise RuntimeError("band 0 failed")
        done.append(r0)
    with pytest.raises(RuntimeError, match="band 0 failed"):
        bands.for_bands(fn, 0, 40, 10)
    assert sorted(done) == [10, 20, 30]


def test_bands_inside_a_band_run_in_line(monkeypatch):
    monkeypatch.setenv("PIXGRAPH_THREADS", "2")
    inner = []

    def outer(r0, r1):
        me = threading.current_thread()
        bands.for_bands(lambda a, b: inner.append(threading.current_thread() is me), 0, 8, 2)
    bands.for_bands(outer, 0, 4, 1)             # 4 outer bands on a 2-thread pool, 4 inner each
    assert len(inner) == 16 and all(inner)


def _photo(tmp_path, H=300, W=200):
    from pixgraph_nodes.ops.imageio import write_image
    rng = np.random.default_rng(2)
    img = rng.uniform(0, 1, (H, W, 3)).astype(np.float32)
    write_image(tmp_path / "p.png", img)
    rgba = np.concatenate([img, rng.uniform(0, 1, (H, W, 1)).astype(np.float32)], axis=2)
    return img, rgba


def test_banded_operations_give_one_threads_numbers(monkeypatch, tmp_path):
    from pixgraph_nodes.ops import composite as C
    from pixgraph_nodes.ops import placement as P
    from pixgraph_nodes.ops import upsample as U
    from pixgraph_nodes.ops.imageio import _decode_srgb8, _encode_srgb8, read_image
    rng = np.random.default_rng(4)
    img, rgba = _photo(tmp_path)
    codes = (rng.uniform(0, 1, (300, 200, 4)) * 255).astype(np.uint8)
    alpha = np.zeros((300, 200), np.float32)
    alpha[50:250, 40:160] = rng.uniform(0, 1, (200, 120))
    dark = rng.uniform(0, 1, (300, 200)).astype(np.float32)
    lo, m_lo = rng.uniform(0, 1, (40, 30)).astype(np.float32), rng.uniform(0, 1, (40, 30)) > 0.5
    m_hi = rng.uniform(0, 1, (300, 200)) > 0.5
    wy = P._weights(60, (np.arange(300) + 0.5) / 4.7, 1.0)
    wx = P._weights(40, (np.arange(200) + 0.5) / 4.7, 1.0)
    planes = rng.uniform(0, 1, (60, 40, 2)).astype(np.float32)

    def every():
        return [read_image(tmp_path / "p.png")[0], *_decode_srgb8(codes), _encode_srgb8(img, None, band=16),
                _encode_srgb8(rgba, 3, band=16),
                C.composite(img, img * alpha[..., None], alpha, dark, 0.8, (0.1, 0.2, 0.3)),
                U.masked_resize(lo, m_lo, m_hi, (300, 200), band=16), P._resample(planes, wy, wx, band=16)]
    monkeypatch.setenv("PIXGRAPH_THREADS", "1")
    one = every()
    monkeypatch.setenv("PIXGRAPH_THREADS", "4")
    four = every()
    for a, b in zip(one, four):
        np.testing.assert_array_equal(a, b)


def _bands_in_a_forked_child(queue):
    seen = []
    bands.for_bands(lambda r0, r1: seen.append(r0), 0, 8, 2)
    queue.put(sorted(seen))


@pytest.mark.filterwarnings("ignore:.*fork.*:DeprecationWarning")     # Python 3.12+: fork with threads
def test_a_forked_child_gets_a_pool_of_its_own(monkeypatch):
    """A process forked after banded work (an embedding host's fork-based workers)
    inherits the pool's bookkeeping but none of its threads: its bands must still run
    (they waited forever on threads that do not exist in the child)."""
    import multiprocessing
    monkeypatch.setenv("PIXGRAPH_THREADS", "2")
    bands.for_bands(lambda r0, r1: None, 0, 8, 2)           # the parent's pool has started its threads
    ctx = multiprocessing.get_context("fork")
    queue = ctx.Queue()
    child = ctx.Process(target=_bands_in_a_forked_child, args=(queue,))
    child.start()
    child.join(60)
    hung = child.is_alive()
    if hung:
        child.kill()
        child.join()
    assert not hung, "the forked child's bands never ran"
    assert queue.get(timeout=5) == [0, 2, 4, 6]


@pytest.mark.parametrize("threads", ["1", "2"])
def test_a_band_below_one_row_still_covers_every_row(monkeypatch, threads):
    """``band`` 0 or less: one row a band (it made empty bands [r, r): no row was
    computed, and an output made with np.empty kept its garbage)."""
    monkeypatch.setenv("PIXGRAPH_THREADS", threads)
    rows = np.zeros(7, int)

    def fn(r0, r1):
        rows[r0:r1] += 1
    bands.for_bands(fn, 0, 7, 0)
    assert rows.tolist() == [1] * 7


@pytest.mark.parametrize("value", ["0", "-2", "2.5"])
def test_a_bad_thread_count_is_the_nodes_error_naming_the_variable(monkeypatch, tmp_path, value):
    """PIXGRAPH_THREADS below 1 is refused like a non-number (0 and -2 silently ran one
    thread), and the run reports it as the node's error, raised in the node's thread."""
    from pixgraph.session import Session
    monkeypatch.setenv("PIXGRAPH_THREADS", value)
    with pytest.raises(ValueError, match="PIXGRAPH_THREADS"):
        bands.workers()
    g = tmp_path / "g.yaml"
    g.write_text("pixgraph: 1\nnodes:\n"
                 "  c: {type: pixgraph.Constant, params: {width: 64, height: 48, color: [0.2, 0.5, 0.8, 1.0]}}\n"
                 "  s: {type: pixgraph.SaveImage, inputs: {image: c.image}, params: {path: out.png}}\n"
                 "outputs: {png: s.path}\n")
    s = Session()
    with pytest.raises(Exception, match=r"(?s)'s'.*PIXGRAPH_THREADS.*" + value):
        s.run(s.load(str(g)), ["png"])
    assert not (tmp_path / "out.png").exists()


@pytest.mark.parametrize("shape_in,shape_out", [((301, 257, 3), (47, 40)), ((300, 200), (75, 200)),
                                                 ((90, 120, 4), (90, 31)), ((64, 64), (80, 50))])
def test_shrink_rows_first_is_resize(monkeypatch, shape_in, shape_out):
    # resample.shrink (rows first, banded; at_scale's path when shrinking) against the
    # column-first resize per channel, the reference it replaced: float rounding only,
    # and the same numbers on one thread and on three
    from pixgraph_nodes.ops import resample
    a = np.random.default_rng(3).random(shape_in, dtype=np.float32)
    chans = a[..., None] if a.ndim == 2 else a
    ref = np.stack([resample.resize(np.ascontiguousarray(chans[..., c]), shape_out)
                    for c in range(chans.shape[2])], -1).reshape(shape_out + a.shape[2:])
    outs = []
    for n in ("1", "3"):
        monkeypatch.setenv("PIXGRAPH_THREADS", n)
        outs.append(resample.shrink(a, shape_out, band=8))
    np.testing.assert_allclose(outs[0], ref, atol=2e-6)
    np.testing.assert_array_equal(outs[0], outs[1])
    if shape_out[0] <= shape_in[0] and shape_out[1] <= shape_in[1]:
        np.testing.assert_array_equal(resample.at_scale(a, shape_out[0] / shape_in[0]).shape[:2],
                                      resample.scaled_size(*shape_in[:2], shape_out[0] / shape_in[0]))
