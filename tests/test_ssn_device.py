"""The torch device SSN++ runs on: PIXGRAPH_TORCH_DEVICE (auto, cpu, cuda, cuda:N),
by default CUDA when torch has it (the brief: on a lent H100 the node ran on the
CPU, 55 ms, where the GPU took 4 ms). This machine has no GPU: what runs here is the
choice, its errors, the per-device copy of the model and the CPU path's numbers."""
import os

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from pixgraph_nodes.ops import ssn  # noqa: E402


def _cuda(monkeypatch, available: bool, count: int = 1):
    monkeypatch.setattr(torch.cuda, "is_available", lambda: available)
    monkeypatch.setattr(torch.cuda, "device_count", lambda: count if available else 0)


def test_auto_takes_cuda_when_torch_has_it(monkeypatch):
    monkeypatch.delenv(ssn.DEVICE_ENV, raising=False)
    _cuda(monkeypatch, False)
    assert ssn.inference_device() == torch.device("cpu")
    _cuda(monkeypatch, True, 2)
    assert ssn.inference_device() == torch.device("cuda")
    monkeypatch.setenv(ssn.DEVICE_ENV, " Auto ")
    assert ssn.inference_device() == torch.device("cuda")
    monkeypatch.setenv(ssn.DEVICE_ENV, "cpu")
    assert ssn.inference_device() == torch.device("cpu")
    monkeypatch.setenv(ssn.DEVICE_ENV, "cuda:1")
    assert ssn.inference_device() == torch.device("cuda", 1)


@pytest.mark.parametrize("value, available, message", [
    ("gpu", True, "must be auto, cpu, cuda or cuda:N"),
    ("cuda:x", True, "must be auto, cpu, cuda or cuda:N"),
    ("mps", True, "must be auto, cpu, cuda or cuda:N"),
    ("cuda", False, "finds no CUDA device"),
    ("cuda:2", True, "finds 2 CUDA device"),
])
def test_bad_settings_name_the_variable(monkeypatch, value, available, message):
    _cuda(monkeypatch, available, 2)
    monkeypatch.setenv(ssn.DEVICE_ENV, value)
    with pytest.raises(ValueError, match=ssn.DEVICE_ENV) as e:
        ssn.inference_device()
    assert message in str(e.value)


def test_the_model_is_copied_once_per_device_and_left_where_it_was():
    torch.manual_seed(0)
    model = ssn.SSN(ssn.SSNConfig(base=4, levels=1)).eval()
    assert ssn.model_on(model, torch.device("cpu")) is model
    meta = ssn.model_on(model, torch.device("meta"))       # a device every torch has
    assert meta is not model and next(meta.parameters()).device.type == "meta"
    assert next(model.parameters()).device.type == "cpu"
    assert ssn.model_on(model, torch.device("meta")) is meta
    other = ssn.SSN(ssn.SSNConfig(base=4, levels=1)).eval()
    assert ssn.model_on(other, torch.device("meta")) is not meta


def test_the_cpu_path_is_the_default_here(monkeypatch):
    """auto on a machine without CUDA and an explicit cpu give the same darkness."""
    monkeypatch.delenv(ssn.DEVICE_ENV, raising=False)
    _cuda(monkeypatch, False)
    torch.manual_seed(1)
    model = ssn.SSN(ssn.SSNConfig(base=4, levels=1)).eval()
    rng = np.random.default_rng(0)
    buffers = {k: rng.random((32, 32)).astype(np.float32) for k in model.config.channels}
    auto = ssn.run_network(model, buffers, 0.2, threads=1)
    cpu = ssn.run_network(model, buffers, 0.2, threads=1, device="cpu")
    assert auto.shape == (32, 32) and auto.dtype == np.float32
    assert np.array_equal(auto, cpu)
    assert 0.0 < float(auto.mean()) < 1.0


@pytest.mark.parametrize("variable, value", [(ssn.DEVICE_ENV, "gpu"), (ssn.THREADS_ENV, "many")])
def test_a_bad_host_setting_is_bad_input(monkeypatch, capsys, variable, value):
    """The node reports a bad PIXGRAPH_TORCH_DEVICE or PIXGRAPH_TORCH_THREADS as bad
    input (exit 2) naming the variable, not a crash."""
    from pixgraph.cli import main

    monkeypatch.setenv(variable, value)
    graph = os.path.join(os.path.dirname(__file__), "..", "graphs", "ssn_wall_corner.yaml")
    code = main(["run", graph, "--no-disk-cache", "-q"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert "node 'shadow' (pixgraph.SoftShadowSSN)" in err[0] and variable in err[0]


def test_a_model_already_on_the_cuda_device_is_not_copied(monkeypatch):
    """``auto`` and ``cuda`` give ``torch.device("cuda")`` (no index), which torch does not
    call equal to ``cuda:0``, where a model moved there has its parameters: such a model
    is run as it is (a copy would double its memory and keep its weights of the first
    call). No GPU here: a stand-in whose parameters say they are on cuda:0."""
    class OnCuda0(torch.nn.Module):
        def parameters(self, recurse=True):
            yield type("P", (), {"device": torch.device("cuda", 0)})()

        def to(self, *a, **k):
            raise AssertionError("copied to another device")

    monkeypatch.setattr(torch.cuda, "current_device", lambda: 0)
    model = OnCuda0()
    assert ssn.model_on(model, torch.device("cuda")) is model
    assert ssn.model_on(model, torch.device("cuda", 0)) is model


def test_the_device_copy_goes_when_its_model_goes():
    """The per-device copies do not keep their models alive: a model dropped by its owner
    (``lab/ssn/methods``' lru_cache of 8 evicting one) is freed with its copy, so no
    other model can later be taken for it by a reused id()."""
    import gc
    import weakref
    model = ssn.SSN(ssn.SSNConfig(base=4, levels=1)).eval()
    copy = ssn.model_on(model, torch.device("meta"))
    gone, copy_gone = weakref.ref(model), weakref.ref(copy)
    del model, copy
    gc.collect()
    assert gone() is None and copy_gone() is None
