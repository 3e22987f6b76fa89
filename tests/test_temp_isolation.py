"""The test session keeps its temporary files in a folder of its own (conftest's
``_private_temp_folder``), so that cleaning up after it never touches another process's
files: a server state's upload folder and a spawned server's TMPDIR lie inside it."""
import os
import subprocess
import sys
import tempfile

from pixgraph_serve.state import ServeState
from serve_helpers import copy_scene


def test_a_server_states_upload_folder_is_the_sessions(_private_temp_folder, tmp_path):
    root = _private_temp_folder
    assert os.path.dirname(root) != root and os.path.isdir(root)
    state = ServeState(copy_scene(str(tmp_path)))
    assert os.path.commonpath([state.upload_dir, root]) == root
    assert not str(tmp_path).startswith(root)      # pytest's own folders stay where pytest keeps them


def test_a_child_process_gets_the_sessions_temp_folder(_private_temp_folder):
    out = subprocess.run([sys.executable, "-c", "import tempfile; print(tempfile.gettempdir())"],
                         capture_output=True, text=True, check=True).stdout.strip()
    assert out == _private_temp_folder == tempfile.gettempdir()
