"""Torch intra-op threads for SSN++ inference (issue 12, item 4): chosen by
PIXGRAPH_TORCH_THREADS or a default, set for the inference only, restored after.
The timing side (idle vs next to busy processes) is benchmarks/ssn_threads_bench.py."""
import os

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from pixgraph_nodes.ops import ssn  # noqa: E402


def test_default_and_env(monkeypatch):
    monkeypatch.delenv(ssn.THREADS_ENV, raising=False)
    cpus = len(os.sched_getaffinity(0))
    assert ssn.inference_threads() == max(1, min(4, cpus // 4))
    monkeypatch.setenv(ssn.THREADS_ENV, " 3 ")
    assert ssn.inference_threads() == 3
    for bad in ("0", "-2", "two", "1.5"):
        monkeypatch.setenv(ssn.THREADS_ENV, bad)
        with pytest.raises(ValueError, match=ssn.THREADS_ENV):
            ssn.inference_threads()


def test_threads_hold_during_inference_and_are_restored(monkeypatch):
    torch.manual_seed(0)
    model = ssn.SSN(ssn.SSNConfig(base=4, levels=1)).eval()
    seen = []
    model.head.register_forward_hook(lambda *a: seen.append(torch.get_num_threads()))
    rng = np.random.default_rng(0)
    buffers = {k: rng.random((32, 32)).astype(np.float32) for k in model.config.channels}
    before = torch.get_num_threads()
    try:
        torch.set_num_threads(2)
        one = ssn.predict(model, buffers, 0.2, threads=1)
        assert seen == [1] and torch.get_num_threads() == 2
        two = ssn.predict(model, buffers, 0.2, threads=2)
        assert seen == [1, 2] and torch.get_num_threads() == 2
        monkeypatch.setenv(ssn.THREADS_ENV, "1")
        ssn.predict(model, buffers, 0.2)
        assert seen == [1, 2, 1] and torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(before)
    assert one.shape == (32, 32)
    np.testing.assert_allclose(one, two, atol=1e-5)


# a bad PIXGRAPH_TORCH_THREADS given to the node: tests/test_ssn_device.py (with the device's)
