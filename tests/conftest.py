"""Shared fixtures. The OpenCL device is opened once per test session."""
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


@pytest.fixture(scope="session", autouse=True)
def _private_temp_folder(tmp_path_factory):
    """Every temporary file of this test session goes in one folder of its own, removed
    at the end: this process's (``tempfile.tempdir``) and those of the servers, browsers
    and workers it starts (they inherit ``TMPDIR``). A server state made without
    ``upload_dir`` leaves its upload folder behind (only a stopping server removes it;
    they piled up in /tmp, 218 MB on the dev machine); removing instead the
    ``pixgraph-uploads-*`` folders that appeared in /tmp during the session also removed
    those of other processes' servers (a ``pixgraph serve`` in use while the tests ran).
    pytest's own ``tmp_path`` folders stay where pytest keeps them."""
    tmp_path_factory.getbasetemp()          # made now, before the temp dir moves
    root = tempfile.mkdtemp(prefix="pixgraph-tests-")
    saved = os.environ.get("TMPDIR"), tempfile.tempdir
    os.environ["TMPDIR"], tempfile.tempdir = root, root
    try:
        yield root
    finally:
        if saved[0] is None:
            os.environ.pop("TMPDIR", None)
        else:
            os.environ["TMPDIR"] = saved[0]
        tempfile.tempdir = saved[1]
        shutil.rmtree(root, ignore_errors=True)
