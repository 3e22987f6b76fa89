"""Bad input found only while running (sizes that do not fit) is exit 2 with one
line naming the node; outputs go to folders that do not exist yet; a kernel that
does not build says why."""
import pathlib

import numpy as np
import pytest

from pixgraph.cli import main
from pixgraph.device import DeviceError
from pixgraph_nodes.ops.imageio import write_image

GRAPHS = pathlib.Path(__file__).resolve().parents[1] / "graphs"


def _run_with_cutout(tmp_path, capsys, img):
    """Run the wall-corner graph with ``img`` as its cutout: (exit code, stderr lines)."""
    path = tmp_path / "cutout.png"
    write_image(path, img)
    code = main(["run", str(GRAPHS / "wall_corner_shadow.yaml"), "--no-disk-cache", "-q",
                 "--set", f"cutout.path={path}", "-o", f"final={tmp_path / 'x.png'}"])
    return code, capsys.readouterr().err.strip().splitlines()


def test_cutout_of_the_wrong_size_is_bad_input_naming_the_node(tmp_path, capsys):
    img = np.zeros((300, 240, 4), np.float32)
    img[140:290, 100:140] = 1.0     # its foot (row 290) lies below the horizon (row 120)
    code, err = _run_with_cutout(tmp_path, capsys, img)
    assert code == 2
    assert len(err) == 1 and "Traceback" not in err[0]
    # the first node that meets both sizes names them
    assert "node 'shadow'" in err[0]
    assert "240x300" in err[0] and "512x512" in err[0]


def test_output_into_a_new_folder(tmp_path):
    out = tmp_path / "new" / "deeper" / "blur.png"
    assert main(["run", str(GRAPHS / "wall_corner_shadow.yaml"), "--no-disk-cache", "-q",
                 "-o", f"final={out}"]) == 0
    assert out.stat().st_size > 10_000


def test_build_error_names_the_compiler_error(device):
    with pytest.raises(DeviceError, match="undeclared identifier 'zz'"):
        device.program("__kernel void k(__global float *a) { a[0] = zz; }")


def test_light_target_above_the_horizon_is_bad_input(tmp_path, capsys):
    img = np.zeros((512, 512, 4), np.float32)
    img[20:90, 200:240] = 1.0       # its foot (row 90) is above the horizon (row 120)
    code, err = _run_with_cutout(tmp_path, capsys, img)
    assert code == 2 and len(err) == 1
    assert "node 'light'" in err[0] and "above the horizon" in err[0]


def test_a_bad_override_is_blamed_on_the_override_not_a_file_line(capsys):
    code = main(["validate", str(GRAPHS / "wall_corner_shadow.yaml"), "--set", "light.elevation=500"])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert "wall_corner_shadow.yaml: node 'light': param 'elevation'" in err
    assert "set by a param override" in err
