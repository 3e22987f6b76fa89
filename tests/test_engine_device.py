"""Devices: listing, selection by spec and environment, a read-only HOME, a host's own context."""
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from pixgraph.cli import main
from pixgraph.device import Device, DeviceError, choose, list_devices
from pixgraph.session import Session


def test_listing_and_default_choice(capsys):
    devices = list_devices()
    assert devices, "no OpenCL device: PoCL should always be there"
    assert all(d.spec == f"{d.platform_index}:{d.device_index}" for d in devices)
    default = choose()
    if not any(d.kind == "GPU" for d in devices):
        # CPU only: Debian's PoCL is preferred when present
        assert ("debian" in default.platform_version.lower()) == any(
            "debian" in d.platform_version.lower() for d in devices)
    assert main(["devices"]) == 0
    out = capsys.readouterr().out
    assert out.count("\n") == len(devices) and f"* [{default.spec}]" in out


def test_selection_by_spec_and_environment(monkeypatch):
    devices = list_devices()
    last = devices[-1]
    assert choose(last.spec) == last
    assert choose(last.name[:12]).name == last.name
    monkeypatch.setenv("PIXGRAPH_DEVICE", last.spec)
    assert choose() == last
    assert Device.open().info == last
    assert choose(devices[0].spec) == devices[0]  # an explicit spec beats the environment
    with pytest.raises(DeviceError, match="no OpenCL device matches 'no-such-device'"):
        choose("no-such-device")


def test_session_device_by_spec_is_lazy_and_used_by_nodes():
    # the default device's spec: the pip PoCL platform cannot build kernels on some
    # CPUs ("unknown target CPU 'generic'"), so do not pick an arbitrary one here
    last = choose()
    s = Session(device=last.spec)
    assert not s.device_opened
    b = s.builder()
    b.add("pixgraph.Constant", "c", width=8, height=6)
    b.add("pixgraph.GaussianBlur", "blur", sigma=1.0)
    b.connect("c.image", "blur.image")
    b.output("o", "blur.image")
    out = s.run(b.build())
    assert s.device_opened and s.device.info == last
    np.testing.assert_allclose(out["o"], np.float32([0.18, 0.18, 0.18, 1.0]) * np.ones((6, 8, 1)), atol=1e-6)


def test_host_hands_in_its_own_context_and_queue():
    import pyopencl as cl

    info = choose()
    dev = cl.get_platforms()[info.platform_index].get_devices()[info.device_index]
    ctx = cl.Context([dev])
    queue = cl.CommandQueue(ctx)
    host = Device.from_cl(ctx, queue)
    s = Session(device=host)
    b = s.builder()
    b.add("pixgraph.GaussianBlur", "blur", sigma=2.0)
    b.add("pixgraph.Constant", "c", width=4, height=4)
    b.connect("c.image", "blur.image")
    b.output("o", "blur.image")
    img = np.random.default_rng(0).uniform(0, 1, (16, 16, 4)).astype(np.float32)
    out = s.run(b.build(), bind={"c": img})["o"]
    from pixgraph_nodes.ops.blur import gaussian_blur_reference

    np.testing.assert_allclose(out, gaussian_blur_reference(img, 2.0), atol=2e-6)
    assert s.device is host and host.context is ctx


def test_bad_device_spec_on_the_command_line(tmp_path, capsys):
    g = tmp_path / "g.yaml"
    g.write_text("pixgraph: 1\nnodes:\n  c: {type: pixgraph.Constant, params: {width: 4, height: 4}}\n"
                 "  b: {type: pixgraph.GaussianBlur, inputs: {image: c.image}}\noutputs: {o: b.image}\n")
    assert main(["run", str(g), "--no-disk-cache", "--device", "no-such-device"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no OpenCL device matches 'no-such-device'" in err


def _unwritable_home(tmp_path) -> str:
    home = tmp_path / "ro-home"
    home.mkdir()
    home.chmod(0o555)
    probe = home / "probe"
    try:
        probe.write_text("x")  # root ignores permissions: use a place nobody can create files in
        probe.unlink()
        return "/proc/1/pixgraph-no-home"
    except OSError:
        return str(home)


def test_works_when_home_is_not_writable(tmp_path):
    home = _unwritable_home(tmp_path)
    env = {k: v for k, v in os.environ.items() if k not in ("XDG_CACHE_HOME", "PIXGRAPH_DISK_CACHE")}
    env["HOME"] = home
    code = textwrap.dedent("""
        import os, numpy as np
        from pixgraph.device import Device, list_devices
        from pixgraph_nodes.ops.blur import gaussian_blur, gaussian_blur_reference
        assert list_devices()
        d = Device.open()
        img = np.random.default_rng(1).uniform(0, 1, (12, 10)).astype(np.float32)
        assert np.allclose(gaussian_blur(d, img, 1.5), gaussian_blur_reference(img, 1.5), atol=2e-6)
        print("cache at", os.environ["XDG_CACHE_HOME"])
    """)
    p = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300,
                       cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert "pixgraph-cache-" in p.stdout
    g = tmp_path / "g.yaml"
    g.write_text("pixgraph: 1\nnodes:\n  c: {type: pixgraph.Constant, params: {width: 4, height: 4}}\n"
                 "  b: {type: pixgraph.GaussianBlur, inputs: {image: c.image}}\noutputs: {o: b.image}\n")
    p = subprocess.run([sys.executable, "-m", "pixgraph", "run", str(g)], env=env, capture_output=True,
                       text=True, timeout=300, cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert "o: array float32 (4, 4, 4)" in p.stdout


def test_program_builds_are_cached_per_device(device):
    src = "__kernel void twice(__global float *x) { x[get_global_id(0)] *= 2.0f; }"
    assert device.program(src) is device.program(src)
    assert device.program(src) is not device.program(src, ("-cl-fast-relaxed-math",))
