"""The machine a benchmark ran on, for its report (shared by the benchmark scripts)."""
from __future__ import annotations

import os
import platform
import subprocess


def cpu_model() -> str:
    """CPU model name and logical CPU count, e.g. ``AMD EPYC (2 logical CPUs)``."""
    model = platform.processor() or ""
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True, timeout=5).stdout
        for line in out.splitlines():
            if line.startswith("Model name:"):
                model = line.split(":", 1)[1].strip()
    except (OSError, subprocess.SubprocessError):
        pass
    return f"{model} ({os.cpu_count()} logical CPUs)"


def peak_rss_mib() -> float:
    """This process's peak resident set (VmHWM) [MiB]; NaN where /proc has none."""
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
    return float("nan")


class NodeContext:
    """The least a node's ``compute`` needs from its context when a benchmark calls it
    directly: the session's ``device``, progress and cancellation doing nothing."""

    def __init__(self, device):
        self.device = device

    def progress(self, *_):
        pass

    def check_cancelled(self):
        pass
