"""Output names up to the file system's limit: a batch's temporary (and the image
writer's temporary on top of it) fit in NAME_MAX (255 bytes) whatever the output
name's length, a name whose sidecar (NAME.json) cannot exist is refused before any
row runs, naming it, and a killed batch's shortened temporaries are still removed.
Before, every output name over ~210 bytes failed its row (ENAMETOOLONG on
``..NAME.tmp-PID-R.tmp-PID-R.png``)."""
import os

import pytest

import pixgraph_batch.files as F
from pixgraph import fileio
from pixgraph.cli import main
from pixgraph.paths import NAME_MAX, TMP_TAIL, temp_stem
from pixgraph.registry import Registry

GRAPH = ("pixgraph: 1\nnodes:\n  c: {type: pixgraph.Constant, params: {width: 8, height: 8, "
         "color: [0.1, 0.2, 0.3, 1]}}\noutputs: {final: c.image}\n")


def _err(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert "\n" not in err, err
    return err


@pytest.mark.parametrize("stem", ["a" * 200, "a" * 246, "é" * 123, "€" * 82, "x" * 300])
@pytest.mark.parametrize("ext", ["", ".png", ".exr", ".json.tmp"])
def test_temp_stem_fits_and_is_stable(stem, ext):
    extra = len(ext.encode())
    short = temp_stem(stem, extra)
    assert 1 + len(short.encode()) + TMP_TAIL + extra <= NAME_MAX
    assert short == temp_stem(stem, extra)                    # leftovers can be told by name
    if 1 + len(stem.encode()) + TMP_TAIL + extra <= NAME_MAX:
        assert short == stem
    else:
        assert stem.startswith(short.rsplit("~", 1)[0]) and short != temp_stem(stem + "b", extra)
    name = f".{short}.tmp-{2 ** 31 - 1}-0a1b2c3d{ext}"           # the longest pid a Linux pid_max allows
    assert len(name.encode()) <= NAME_MAX


@pytest.mark.parametrize("n", [215, 230, 246])
def test_a_batch_writes_long_output_names(tmp_path, capsys, n):
    (tmp_path / "g.yaml").write_text(GRAPH)
    rid = "é" * (n // 2) + "a" * (n % 2) if n == 230 else "a" * n       # bytes, not characters, count
    (tmp_path / "rows.csv").write_text(f"id,c.width\n{rid},8\nshort,9\n", encoding="utf-8")
    out = tmp_path / "out"
    args = ["batch", str(tmp_path / "g.yaml"), str(tmp_path / "rows.csv"), "--no-disk-cache",
            "-o", f"final={out}/{{row}}.png"]
    assert main(args) == 0, capsys.readouterr()
    name = rid + ".png"
    assert sorted(os.listdir(out)) == sorted([name, name + ".json", "short.png", "short.png.json"])
    assert len((name + ".json").encode()) <= NAME_MAX
    capsys.readouterr()
    assert main(args) == 0                                      # resumed: both done already
    assert "2 skipped" in capsys.readouterr().out


def test_a_name_whose_sidecar_cannot_exist_is_refused_before_any_row(tmp_path, capsys):
    (tmp_path / "g.yaml").write_text(GRAPH)
    (tmp_path / "rows.csv").write_text("id,c.width\nshort,9\n" + "a" * 247 + ",8\n")
    rc = main(["batch", str(tmp_path / "g.yaml"), str(tmp_path / "rows.csv"), "--no-disk-cache",
               "-o", f"final={tmp_path}/out/{{row}}.png"])
    assert rc == 2
    err = _err(capsys)
    assert err.startswith(f"{tmp_path / 'rows.csv'}:3: output final: ") and "256 bytes, over the 255" in err
    assert not (tmp_path / "out").exists()


def test_leftover_shortened_temporaries_are_removed(tmp_path):
    dead = 2 ** 22 + 12345
    out = "b" * 250 + ".png"
    names = [os.path.basename(F.temporary_name(str(tmp_path / out))).replace(f"-{os.getpid()}-", f"-{dead}-"),
             os.path.basename(F.temporary_name(str(tmp_path / (out + ".json")), suffix=".tmp"))
             .replace(f"-{os.getpid()}-", f"-{dead}-")]
    names.append(f".{names[0][:-4]}.tmp-{dead}-0a1b2c3d.png")     # the image writer's inside the batch's
    assert all(len(n.encode()) <= NAME_MAX for n in names), [len(n) for n in names]
    for n in names:
        (tmp_path / n).write_bytes(b"x")
    (tmp_path / "keep.png").write_bytes(b"x")
    removed = F.remove_temporaries([str(tmp_path / out)])
    assert sorted(os.path.basename(p) for p in removed) == sorted(names)
    assert os.listdir(tmp_path) == ["keep.png"]


def test_a_graph_saved_under_a_long_name(tmp_path):
    reg = Registry.discover()
    graph = fileio.loads(GRAPH, reg)
    path = tmp_path / ("g" * 250 + ".yaml")
    fileio.dump(graph, str(path))
    assert os.listdir(tmp_path) == [path.name]


def test_a_planted_temporary_with_a_unicode_digit_pid_is_left_alone(tmp_path):
    """'²' is a digit to str.isdigit and not to int(): a file ``.r03.tmp-²-0.png``
    planted in the output folder made every batch on it stop with a ValueError."""
    planted = tmp_path / ".r03.tmp-\u00b2-0a1b2c3d.png"
    planted.write_bytes(b"x")
    assert F.remove_temporaries([str(tmp_path / "r03.png")]) == []
    assert planted.exists()
