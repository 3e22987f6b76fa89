"""Rows of a batch: manifests (CSV, TSV, YAML) and sweeps, bounded before they are expanded.

A *row* binds ``node.param`` overrides (input files are ``LoadImage.path``
params) and other columns (fields for output templates). Rows come from a
manifest, from sweeps (``light.azimuth=0:360:15``) or both (every manifest row
crossed with every combination of sweep values).

Bounds, checked before anything is expanded (so a hostile or mistyped input is
refused at once, in constant memory):

- a manifest file is at most ``max_manifest_bytes`` (default 64 MiB);
- a YAML manifest is read with safe YAML that refuses anchors and aliases (no
  "billion laughs" expansion);
- the number of rows (manifest rows x sweep values) is at most ``max_rows``
  (default 100,000; ``--max-rows`` raises it); a range sweep's length is
  computed arithmetically, never by listing it;
- range sweeps take finite numbers only (``0:10:nan`` is refused).
"""
from __future__ import annotations

import csv
import dataclasses
import glob
import itertools
import math
import os
from typing import Any, Mapping, Sequence

import yaml

from pixgraph.graph import GraphError, split_param

#: defaults of the bounds (``--max-rows``, ``--max-manifest-bytes``)
DEFAULT_MAX_ROWS = 100_000
DEFAULT_MAX_MANIFEST_BYTES = 64 << 20


class BatchError(ValueError):
    """A manifest, sweep, template or output folder that cannot make a batch (bad input, exit 2)."""


@dataclasses.dataclass(frozen=True)
class Row:
    """One manifest or sweep row: ``params`` are ``node.param`` overrides, ``fields``
    the other columns (usable in output templates), ``source`` where it came from."""

    id: str
    params: Mapping[str, Any]
    fields: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    source: str = ""


def is_param_name(name: str) -> bool:
    """True for a ``node.param`` column (``pixgraph.graph.split_param`` accepts it)."""
    try:
        split_param(name)
        return True
    except GraphError:
        return False


# -- manifests -----------------------------------------------------------------------


def read_manifest(path: str | os.PathLike, max_rows: int = DEFAULT_MAX_ROWS,
                  max_bytes: int = DEFAULT_MAX_MANIFEST_BYTES) -> list[Row]:
    """Rows of a CSV, TSV or YAML manifest.

    CSV: a header row; columns named ``node.param`` are overrides (cells are YAML
    scalars or lists, an empty cell leaves the graph's value), other columns are
    fields for templates (``id`` names the row). YAML: a list of mappings, or a
    mapping with ``rows:``, each mapping like a CSV row (a node's params may be
    grouped: ``{light: {azimuth: 5}}``); anchors and aliases are refused. Relative
    paths of path params are resolved against the manifest's folder when the
    batch is planned. A file over ``max_bytes`` or with more than ``max_rows``
    rows is a ``BatchError`` naming the limit and the option that raises it.
    """
    path = os.fspath(path)
    lower = path.lower()
    if not lower.endswith((".yaml", ".yml", ".csv", ".tsv")):
        raise BatchError(f"{path}: a manifest is .csv, .tsv, .yaml or .yml")
    try:
        size = os.path.getsize(path)
        if size > max_bytes:
            raise BatchError(f"{path}: manifest of {size} bytes is over the limit of {max_bytes} bytes "
                             f"(raise it with --max-manifest-bytes)")
        with open(path, newline="", encoding="utf-8") as f:
            text = f.read(max_bytes + 1)
    except OSError as e:
        raise BatchError(f"{path}: cannot read manifest: {e.strerror}") from None
    except UnicodeDecodeError as e:
        raise BatchError(f"{path}: not UTF-8 text ({e.reason} at byte {e.start})") from None
    if lower.endswith((".yaml", ".yml")):
        return _yaml_rows(path, text, max_rows)
    return _csv_rows(path, text, max_rows)


def _too_many(what: str, n: int, max_rows: int) -> BatchError:
    return BatchError(f"{what}: {n} rows, over the limit of {max_rows} rows per batch (raise it with --max-rows)")


def _csv_rows(path: str, text: str, max_rows: int) -> list[Row]:
    dialect = csv.excel_tab if path.lower().endswith(".tsv") else csv.excel
    reader = csv.reader(text.splitlines(), dialect)
    try:
        header = [h.strip() for h in next(reader)]
    except StopIteration:
        raise BatchError(f"{path}: empty manifest (expected a header row)") from None
    except csv.Error as e:
        raise BatchError(f"{path}:1: not valid CSV: {e}") from None
    if len(set(header)) != len(header) or "" in header:
        raise BatchError(f"{path}:1: header has an empty or repeated column name")
    out = []
    lineno = 1
    try:
        for cells in reader:
            lineno = reader.line_num
            if not any(c.strip() for c in cells):
                continue
            if len(out) >= max_rows:
                raise _too_many(path, len(out) + 1, max_rows)
            if len(cells) != len(header):
                raise BatchError(f"{path}:{lineno}: {len(cells)} cells, the header has {len(header)}")
            values = {}
            for name, cell in zip(header, cells):
                if cell.strip() == "":
                    continue
                if is_param_name(name):
                    values[name] = _yaml_value(cell, f"{path}:{lineno}: column {name!r}")
                else:
                    values[name] = cell
            out.append(make_row(values, f"{path}:{lineno}"))
    except csv.Error as e:
        raise BatchError(f"{path}:{lineno}: not valid CSV: {e}") from None
    return out


class _AliasRefused(Exception):
    def __init__(self, line: int):
        super().__init__(line)
        self.line = line


class _NoAliasLoader(yaml.SafeLoader):
    """Safe YAML that refuses anchors (``&a``) and aliases (``*a``): a manifest is
    plain data, and aliases let a few bytes expand into gigabytes."""

    def compose_node(self, parent, index):
        event = self.peek_event()
        if isinstance(event, yaml.AliasEvent) or getattr(event, "anchor", None):
            raise _AliasRefused(event.start_mark.line + 1)
        return super().compose_node(parent, index)


def safe_load(text: str, where: str) -> Any:
    """``text`` as plain YAML data (no anchors, aliases or tags beyond safe YAML's);
    errors are ``BatchError`` naming ``where``."""
    try:
        return yaml.load(text, Loader=_NoAliasLoader)  # noqa: S506 - a SafeLoader subclass
    except _AliasRefused as e:
        raise BatchError(f"{where}:{e.line}: YAML anchors and aliases (&name, *name) are not allowed "
                         f"in a manifest") from None
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        line = f":{mark.line + 1}" if mark is not None else ""
        raise BatchError(f"{where}{line}: not valid YAML: {str(e).splitlines()[0]}") from None
    except RecursionError:
        raise BatchError(f"{where}: YAML nested too deeply") from None
    except ValueError as e:     # an integer over Python's limit of 4300 digits
        raise BatchError(f"{where}: not valid YAML: {str(e).split(';')[0]}") from None


def _yaml_value(text: str, where: str) -> Any:
    return safe_load(text, where)


def _yaml_rows(path: str, text: str, max_rows: int) -> list[Row]:
    data = safe_load(text, path)
    if isinstance(data, Mapping) and "rows" in data:
        data = data["rows"]
    if not isinstance(data, list):
        raise BatchError(f"{path}: a YAML manifest is a list of rows (or a mapping with 'rows:')")
    if len(data) > max_rows:
        raise _too_many(path, len(data), max_rows)
    out = []
    for i, item in enumerate(data):
        if not isinstance(item, Mapping):
            raise BatchError(f"{path}: row {i}: expected a mapping of column: value")
        values = {}
        for name, value in item.items():
            if isinstance(value, Mapping) and "." not in str(name):  # {node: {param: value}}
                values.update({f"{name}.{k}": v for k, v in value.items()})
            else:
                values[str(name)] = value
        out.append(make_row(values, f"{path}: row {i}"))
    return out


def make_row(values: Mapping[str, Any], source: str) -> Row:
    """A ``Row`` from column -> value: ``node.param`` columns are overrides, the
    others fields (``id`` names the row)."""
    params = {k: v for k, v in values.items() if is_param_name(k)}
    fields = {k: v for k, v in values.items() if k not in params}
    rid = fields.get("id")
    return Row("" if rid is None else str(rid), params, fields, source)


# -- sweeps --------------------------------------------------------------------------


def parse_sweep(spec: str, max_values: int = DEFAULT_MAX_ROWS) -> tuple[str, list[Any]]:
    """``NODE.PARAM=VALUES`` -> (name, values). VALUES is ``start:stop:step``
    (stop excluded, like ``range``: ``0:360:15`` is 0, 15, .., 345; finite numbers
    only), a comma-separated list of YAML values, or a file glob (``cutouts/*.png``).
    More than ``max_values`` values is a ``BatchError`` raised before any is made."""
    name, eq, raw = spec.partition("=")
    name, raw = name.strip(), raw.strip()
    if not eq or not raw or not is_param_name(name):
        raise BatchError(f"--sweep {spec}: expected NODE.PARAM=START:STOP:STEP, A,B,C or a file glob")
    if any(ch in raw for ch in "*?["):
        files = []
        for f in glob.iglob(raw):
            if len(files) >= max_values:
                raise BatchError(f"--sweep {spec}: more than {max_values} files match, over the limit of "
                                 f"{max_values} rows per batch (raise it with --max-rows)")
            files.append(f)
        if not files:
            raise BatchError(f"--sweep {spec}: no file matches {raw!r}")
        return name, [os.path.abspath(f) for f in sorted(files)]
    if raw.count(":") == 2:
        return name, _range_values(spec, raw, max_values)
    parts = raw.split(",")
    if len(parts) > max_values:
        raise BatchError(f"--sweep {spec}: {len(parts)} values, over the limit of {max_values} rows per batch "
                         f"(raise it with --max-rows)")
    return name, [_yaml_value(x, f"--sweep {spec}") for x in parts]


def _range_values(spec: str, raw: str, max_values: int) -> list[Any]:
    try:
        start, stop, step = (float(x) for x in raw.split(":"))
    except ValueError:
        raise BatchError(f"--sweep {spec}: START:STOP:STEP must be numbers") from None
    if not all(math.isfinite(x) for x in (start, stop, step)):
        raise BatchError(f"--sweep {spec}: START, STOP and STEP must be finite numbers")
    if step == 0 or (stop - start) / step <= 0:
        raise BatchError(f"--sweep {spec}: the range is empty (step 0 or pointing away from stop)")
    count = (stop - start) / step
    if not math.isfinite(count) or count > max_values + 1:
        raise BatchError(f"--sweep {spec}: {count:.6g} values, over the limit of {max_values} rows per batch "
                         f"(raise it with --max-rows)")
    n = math.ceil(count - 1e-9)
    if n > max_values:
        raise BatchError(f"--sweep {spec}: {n} values, over the limit of {max_values} rows per batch "
                         f"(raise it with --max-rows)")
    values = [start + i * step for i in range(n)]
    if all(float(x).is_integer() for x in (start, step)):
        return [int(round(v)) for v in values]
    return values


def count_rows(sweeps: Sequence[tuple[str, Sequence[Any]]], base: Sequence[Row] | None) -> int:
    """How many rows ``sweep_rows`` would make (a product, computed without making them)."""
    n = max(1, len(base or ()))
    for _, values in sweeps:
        n *= len(values)
    return n


def sweep_rows(sweeps: Sequence[tuple[str, Sequence[Any]]], base: Sequence[Row] | None = None,
               max_rows: int = DEFAULT_MAX_ROWS) -> list[Row]:
    """Every base row (one empty row when none) crossed with every combination of
    sweep values (the last sweep varies fastest). More than ``max_rows`` rows is a
    ``BatchError``, raised before any row is made."""
    n = count_rows(sweeps, base)
    if n > max_rows:
        sizes = " x ".join([str(len(base))] * bool(base) + [str(len(v)) for _, v in sweeps])
        raise BatchError(f"{sizes} = {n} rows, over the limit of {max_rows} rows per batch "
                         f"(raise it with --max-rows)")
    base = list(base) if base else [Row("", {}, {}, "")]
    if not sweeps:
        return base
    names = [n for n, _ in sweeps]
    out = []
    for row in base:
        for combo in itertools.product(*(v for _, v in sweeps)):
            params = dict(row.params)
            params.update(zip(names, combo))
            label = " ".join(f"{n}={short(v)}" for n, v in zip(names, combo))
            out.append(Row(row.id, params, dict(row.fields), f"{row.source} {label}".strip()))
    return out


def short(v) -> str:
    """A value as a template field: a file path by its name, anything else as ``str``."""
    return os.path.basename(v) if isinstance(v, str) and os.path.isabs(v) else str(v)
