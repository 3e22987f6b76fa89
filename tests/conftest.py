"""Shared fixtures. The OpenCL device is opened once per test session."""
import glob
import os
import shutil
import tempfile

import pytest

from pixgraph.device import Device


@pytest.fixture(scope="session")
def device():
    """The default OpenCL device (PIXGRAPH_DEVICE overrides), shared by all tests."""
    return Device.open()


@pytest.fixture(scope="session", params=["pip", "debian"])
def each_pocl(request):
    """Each installed PoCL platform in turn (skipped when that one is absent)."""
    from pixgraph.device import build_problem, list_devices
    want_debian = request.param == "debian"
    for d in list_devices():
        if d.kind == "CPU" and ("debian" in d.platform_version.lower()) == want_debian:
            problem = build_problem(d)
            if problem:
                pytest.skip(f"the {request.param} PoCL platform cannot build kernels here: {problem}")
            return Device.open(d.spec)
    pytest.skip(f"no {request.param} PoCL platform installed")


def _upload_folders():
    return set(glob.glob(os.path.join(tempfile.gettempdir(), "pixgraph-uploads-*")))


@pytest.fixture(scope="session", autouse=True)
def _no_upload_folders_left_behind():
    """A server state made in this process (``ServeState`` without ``upload_dir``) makes
    an upload folder that only a stopping server removes: the folders this test session
    made are removed at its end (they piled up in /tmp, 218 MB on the dev machine)."""
    before = _upload_folders()
    yield
    for d in _upload_folders() - before:
        shutil.rmtree(d, ignore_errors=True)
