"""Check that pixgraph's dependencies resolve to binary wheels on other platforms.

For each target (macOS arm64, Windows x86-64, Linux aarch64, and Linux x86-64 for
comparison) this evaluates the environment markers of pyproject.toml's
dependencies *for that target* (pip evaluates markers against the machine it runs
on, even with ``--platform``, and takes each ``--platform`` tag literally, so a
target lists the tags an installer there would accept) and asks pip to resolve what is left with
``--only-binary=:all:`` for that platform, without installing anything:

    python tools/check_install_platforms.py             # base install
    python tools/check_install_platforms.py --extra ssn # plus the extra's own wheels

An extra's packages are checked with ``--no-deps`` (is there a wheel of the pinned
version for that platform?): pip also evaluates the markers of *their* dependencies
against this machine, so torch resolved "for macOS" from Linux asks for CUDA
packages that macOS never installs.

Prints each target's pip command and resolved packages; exit status 1 if any
target fails. Needs the package index (network) and `packaging` (installed with pytest).
"""
from __future__ import annotations

import argparse
import concurrent.futures
import json
import pathlib
import subprocess
import sys
import tempfile
import tomllib

from packaging.requirements import Requirement

ROOT = pathlib.Path(__file__).resolve().parents[1]

#: name: (pip --platform tags, marker environment)
TARGETS = {
    "macos-arm64": ([f"macosx_{v}_0_arm64" for v in (14, 13, 12, 11)],
                    {"sys_platform": "darwin", "platform_system": "Darwin", "platform_machine": "arm64",
                     "os_name": "posix"}),
    "windows-x86_64": (["win_amd64"],
                       {"sys_platform": "win32", "platform_system": "Windows", "platform_machine": "AMD64",
                        "os_name": "nt"}),
    "linux-aarch64": ([f"manylinux_2_{v}_aarch64" for v in (28, 27, 26, 17)] + ["manylinux2014_aarch64"],
                      {"sys_platform": "linux", "platform_system": "Linux", "platform_machine": "aarch64",
                       "os_name": "posix"}),
    "linux-x86_64": ([f"manylinux_2_{v}_x86_64" for v in (28, 27, 26, 17)] + ["manylinux2014_x86_64"],
                     {"sys_platform": "linux", "platform_system": "Linux", "platform_machine": "x86_64",
                      "os_name": "posix"}),
}


def requirements(extras: list[str] | None, env: dict) -> list[str]:
    """pyproject's dependencies (or, given ``extras``, only theirs) whose markers hold
    in ``env``, markers dropped."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    if extras is None:
        lines = list(project["dependencies"])
    else:
        lines = [r for extra in extras for r in project["optional-dependencies"][extra]]
    out = []
    for line in lines:
        req = Requirement(line)
        full = {"python_version": PYTHON, "python_full_version": PYTHON + ".0", "implementation_name": "cpython",
                "platform_python_implementation": "CPython", "extra": "", **env}
        if req.marker is None or req.marker.evaluate(full):
            req.marker = None
            out.append(str(req))
    return out


def resolve(target: str, extras: list[str] | None = None) -> tuple[bool, str, list[str]]:
    """Resolve the base dependencies (``extras`` None) or, with ``--no-deps``, the extras'."""
    platforms, env = TARGETS[target]
    reqs = requirements(extras, env)
    with tempfile.TemporaryDirectory() as tmp:
        report = pathlib.Path(tmp) / "report.json"
        cmd = [sys.executable, "-m", "pip", "install", "--dry-run", "--quiet", "--ignore-installed",
               "--only-binary=:all:", "--python-version", PYTHON, "--target", str(pathlib.Path(tmp) / "t"),
               "--report", str(report)]
        for p in platforms:
            cmd += ["--platform", p]
        if extras is not None:
            cmd.append("--no-deps")
        cmd += reqs
        proc = subprocess.run(cmd, capture_output=True, text=True)
        shown = " ".join(a if " " not in a and ";" not in a else repr(a) for a in cmd[1:])
        if proc.returncode != 0:
            err = [ln for ln in proc.stderr.splitlines() if ln.startswith("ERROR")]
            return False, shown, err or proc.stderr.splitlines()[-3:]
        installed = json.loads(report.read_text())["install"]
        return True, shown, [f"{i['metadata']['name']}=={i['metadata']['version']} "
                             f"({i['download_info']['url'].rsplit('/', 1)[-1]})" for i in installed]


PYTHON = "3.11"


def main(argv=None) -> int:
    global PYTHON
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--extra", action="append", default=[], help="also resolve this extra (repeatable)")
    ap.add_argument("--target", action="append", choices=sorted(TARGETS), help="default: all")
    ap.add_argument("--python", default=PYTHON, help="target Python version (default 3.11)")
    args = ap.parse_args(argv)
    PYTHON = args.python
    jobs = [(target, what, extras) for target in args.target or list(TARGETS)
            for what, extras in [("base", None)] + ([(f"extras {args.extra}", args.extra)] if args.extra else [])]
    with concurrent.futures.ThreadPoolExecutor(4) as pool:     # pip waits on the index, not the CPU
        results = list(pool.map(lambda job: resolve(job[0], job[2]), jobs))
    failed = 0
    for (target, what, _), (ok, cmd, lines) in zip(jobs, results):
        print(f"== {target} {what}: {'ok' if ok else 'FAILED'}\n$ python {cmd}")
        for ln in lines:
            print("   " + ln)
        failed += not ok
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
