"""Command-line option parsers that the CLI and the shells share: ``--set
NODE.PARAM=VALUE`` and ``-o NAME=PATH`` (one parser each), and the one reader of
numbers set in the environment (``env_int``)."""
from __future__ import annotations

import os
from typing import Any

import yaml

from .errors import UsageError


def parse_sets(items: list[str]) -> dict[str, Any]:
    """``["blur.sigma=4", "m.color=[1, 0, 0]"]`` -> ``{"blur.sigma": 4, ...}`` (safe YAML values)."""
    out = {}
    for item in items:
        name, eq, raw = item.partition("=")
        if not eq or "." not in name:
            raise UsageError(f"--set {item}: expected NODE.PARAM=VALUE")
        try:
            out[name.strip()] = yaml.safe_load(raw) if raw.strip() else ""
        except (yaml.YAMLError, ValueError) as e:     # ValueError: an int over Python's 4300 digits
            shown = item if len(item) <= 120 else item[:100] + "..."
            raise UsageError(f"--set {shown}: value is not valid YAML: {str(e).splitlines()[0].split(';')[0]}") from None
    return out


def parse_output_options(options, value: str = "PATH") -> dict[str, str]:
    """``-o NAME=PATH`` options (``pixgraph run``; ``pixgraph batch`` with a
    template as the value) -> ``{name: value}``; raises ``UsageError``."""
    outputs = {}
    for item in options or ():
        name, eq, text = item.partition("=")
        if not eq or not name or not text:
            raise UsageError(f"-o {item}: expected NAME={value}")
        outputs[name] = text
    return outputs


def env_int(name: str, default: int, what: str = "a number") -> int:
    """The integer in the environment variable ``name`` (``1e9`` allowed, truncated;
    unset or blank: ``default``); ValueError naming the variable for anything else,
    ``inf`` and ``1e400`` included (``int(float())`` of those raises OverflowError)."""
    raw = os.environ.get(name, "")
    if not raw.strip():
        return default
    try:
        return int(float(raw))
    except (ValueError, OverflowError):
        raise ValueError(f"{name} must be {what}, got {raw[:40]!r}") from None
