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


@pytest.mark.parametrize("graph, args, node", [
    ("ssn_wall_corner.yaml", [], "node 'shadow' (pixgraph.SoftShadowSSN)"),
    ("auto_shadow.yaml", ["--set", "shadow.method=ssn"], "node 'shadow' (pixgraph.Shadow)"),
])
@pytest.mark.parametrize("variable, value", [(ssn.DEVICE_ENV, "gpu"), (ssn.THREADS_ENV, "many")])
def test_a_bad_host_setting_is_bad_input(monkeypatch, capsys, variable, value, graph, args, node):
    """SSN++ (its own node, or pixgraph.Shadow running it) reports a bad
    PIXGRAPH_TORCH_DEVICE or PIXGRAPH_TORCH_THREADS as bad input (exit 2) naming the
    variable, not a crash (pixgraph.Shadow used to fail with exit 1)."""
    from pixgraph.cli import main

    monkeypatch.setenv(variable, value)
    path = os.path.join(os.path.dirname(__file__), "..", "graphs", graph)
    code = main(["run", path, *args, "--no-disk-cache", "-q"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert node in err[0] and variable in err[0]
