"""What a host installs: no torch unless SSN++ runs, PoCL's wheel only where it
exists, a clear message where OpenCL is missing, wheels for other platforms."""
from __future__ import annotations

import json
import pathlib
import subprocess
import sys
import tomllib

import pytest
from packaging.requirements import Requirement

from pixgraph.device import no_device_hint

ROOT = pathlib.Path(__file__).resolve().parents[1]

# Runs the CLI's main in a fresh interpreter and reports which heavy modules got imported.
_PROBE = """
import json, sys
from pixgraph.cli import main
try:
    main(sys.argv[1:])
except SystemExit as e:
    code = e.code
else:
    code = 0
heavy = ("torch", "kornia", "matplotlib")  # networkx is the graph model: a base dependency
print(json.dumps({"code": code, "loaded": [m for m in heavy if m in sys.modules]}))
"""


def _probe(tmp_path, *args, before=""):
    script = tmp_path / "probe.py"
    script.write_text(before + _PROBE)
    proc = subprocess.run([sys.executable, str(script), *args], capture_output=True, text=True, cwd=ROOT,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_run_without_ssn_imports_no_torch(tmp_path):
    out = tmp_path / "o.png"
    r = _probe(tmp_path, "run", "graphs/ground_shadow.yaml", "--set", "shadow.samples=4",
               "-o", f"final={out}", "--no-disk-cache")
    assert r == {"code": 0, "loaded": []}
    assert out.stat().st_size > 0


def test_validating_an_ssn_graph_imports_no_torch(tmp_path):
    # the node is registered (its ports and params are known) without loading torch
    r = _probe(tmp_path, "validate", "graphs/ssn_wall_corner.yaml")
    assert r == {"code": 0, "loaded": []}


def test_the_probe_sees_torch_when_ssn_loads(tmp_path):
    # the same probe, with SSN++'s ops loaded as when the node runs: the check can fail
    r = _probe(tmp_path, "validate", "graphs/ssn_wall_corner.yaml",
               before="from pixgraph_nodes import ssn_soft_shadow\nssn_soft_shadow._ssn()\n")
    assert r["loaded"] == ["torch"]


def _deps():
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]


def test_base_install_has_no_torch_and_pocl_only_where_its_wheel_exists():
    base = {Requirement(r).name.lower(): Requirement(r) for r in _deps()["dependencies"]}
    assert not {"torch", "kornia", "matplotlib"} & set(base) and "networkx" in base
    pocl = base["pocl-binary-distribution"].marker
    env = {"platform_system": "Linux", "platform_machine": "x86_64"}
    assert pocl.evaluate(env)
    for system, machine in [("Darwin", "arm64"), ("Windows", "AMD64"), ("Linux", "aarch64")]:
        assert not pocl.evaluate({"platform_system": system, "platform_machine": machine})
    assert any(Requirement(r).name == "torch" for r in _deps()["optional-dependencies"]["ssn"])


@pytest.mark.parametrize("system, machine, needle", [
    ("Darwin", "arm64", "brew install pocl"),
    ("Windows", "AMD64", "GPU vendor's driver"),
    ("Linux", "aarch64", "no PoCL wheel exists for Linux aarch64"),
    ("Linux", "x86_64", "pip install pocl-binary-distribution"),
])
def test_no_device_hint_names_what_to_install(system, machine, needle):
    hint = no_device_hint(system, machine)
    assert needle in hint and "\n" not in hint


def test_ssn_without_torch_names_the_extra(monkeypatch):
    import pixgraph_nodes.ops
    from pixgraph_nodes import ssn_soft_shadow

    monkeypatch.setitem(sys.modules, "torch", None)          # import torch -> ModuleNotFoundError
    monkeypatch.delitem(sys.modules, "pixgraph_nodes.ops.ssn", raising=False)   # as if never imported
    monkeypatch.delattr(pixgraph_nodes.ops, "ssn", raising=False)
    with pytest.raises(ModuleNotFoundError, match=r"pip install 'pixgraph\[ssn\]'"):
        ssn_soft_shadow._ssn()


@pytest.mark.network
def test_wheels_resolve_for_macos_windows_linux_arm():
    proc = subprocess.run([sys.executable, "tools/check_install_platforms.py", "--extra", "ssn",
                           "--target", "macos-arm64", "--target", "windows-x86_64", "--target", "linux-aarch64"],
                          capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    for target in ("macos-arm64", "windows-x86_64", "linux-aarch64"):
        assert f"== {target} base: ok" in proc.stdout
        assert f"== {target} extras ['ssn']: ok" in proc.stdout
    assert "pyopencl==" in proc.stdout and "pocl-binary-distribution" not in proc.stdout
