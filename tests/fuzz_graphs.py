"""Graph-file fuzzing: mutate the example graphs in ``graphs/`` and run each
mutant through the CLI (``pixgraph run``) in a worker process.

A worker runs cases one after another (so the imports and the OpenCL device are
paid once) with a memory limit; the parent gives each case ``CASE_TIMEOUT_S``
and replaces a worker that hangs or dies. Used by ``tests/test_fuzz_graphs.py``;
also a script::

    python tests/fuzz_graphs.py --cases 300 --seed 7      # prints the outcome counts
"""
from __future__ import annotations

import argparse
import collections
import contextlib
import json
import os
import random
import select
import shutil
import subprocess
import sys
import time

import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
GRAPHS = os.path.join(ROOT, "graphs")
CASE_TIMEOUT_S = 30.0
MAX_LINE = 300
#: address space a worker may use (a hostile size must fail, not swap the machine)
WORKER_MEMORY_BYTES = 3 << 30

HOSTILE = [0, -1, 1, 3, 2 ** 31, 10 ** 30, -10 ** 30, 1e300, -1e300, float("nan"), float("inf"), -float("inf"),
           1e-300, -0.0, 65536, 4097, "", "x" * 5000, "../../../../etc/passwd", "/etc/passwd", "~/.bashrc",
           "a\0b.png", "out/\x1b[2J.png", "/dev/zero", "assets", [], [1.0, 2.0], [1e300] * 4, {}, {"a": 1},
           None, True, "nan", "1e999", [float("nan")] * 4, list(range(1000))]
BOMB = ("bomb: &a0 [x,x,x,x,x,x,x,x,x,x]\n" + "".join(
    f"b{i}: &a{i} [*a{i-1},*a{i-1},*a{i-1},*a{i-1},*a{i-1},*a{i-1},*a{i-1},*a{i-1},*a{i-1},*a{i-1}]\n"
    for i in range(1, 9)))


def examples() -> dict[str, str]:
    return {n: open(os.path.join(GRAPHS, n), encoding="utf-8").read()
            for n in sorted(os.listdir(GRAPHS)) if n.endswith(".yaml")}


def _node_types() -> list[str]:
    types = set()
    for text in examples().values():
        for n in (yaml.safe_load(text).get("nodes") or {}).values():
            types.add(n["type"])
    return sorted(types)


def mutate(text: str, rng: random.Random, types: list[str]) -> tuple[str, str]:
    """One mutant of a graph file's text, and the name of the mutation."""
    kind = rng.choice(["param", "param", "param", "drop_node", "rewire", "retype", "extra_key", "swap_params",
                       "drop_line", "dup_line", "swap_lines", "truncate", "bytes", "number", "bomb", "deep",
                       "long", "recursive", "two"])
    if kind == "two":
        text, a = mutate(text, rng, types)
        text, b = mutate(text, rng, types)
        return text, f"{a}+{b}"
    lines = text.splitlines(keepends=True)
    if kind in ("drop_line", "dup_line", "swap_lines") and len(lines) > 2:
        i, j = rng.randrange(len(lines)), rng.randrange(len(lines))
        if kind == "drop_line":
            del lines[i]
        elif kind == "dup_line":
            lines.insert(i, lines[j])
        else:
            lines[i], lines[j] = lines[j], lines[i]
        return "".join(lines), kind
    if kind == "truncate":
        return text[: rng.randrange(len(text))], kind
    if kind == "bytes":
        b = bytearray(text.encode("utf-8"))
        for _ in range(rng.randint(1, 4)):
            b[rng.randrange(len(b))] = rng.choice([0, 0xFF, 0x1B, ord(":"), ord("&"), ord("*"), ord("["),
                                                   ord("!"), ord("\n"), rng.randrange(256)])
        return b.decode("utf-8", errors="surrogateescape").encode("utf-8", "replace").decode("utf-8"), kind
    if kind == "number":
        import re

        nums = list(re.finditer(r"(?<![\w.])-?\d+(\.\d+)?(e[-+]?\d+)?", text))
        if nums:
            m = rng.choice(nums)
            new = rng.choice(["1e308", "-1e308", "99999999999999999999999", "0", "-0.0", ".nan", ".inf", "-.inf",
                              "1e-320", "65536", "-7"])
            return text[: m.start()] + new + text[m.end():], kind
    if kind == "bomb":
        return text + BOMB, kind
    if kind == "deep":
        return text + "deep: " + "[" * 200 + "]" * 200 + "\n", kind
    if kind == "long":
        return text.replace("type:", "type: " + "Q" * 200_000 + " #", 1), kind
    if kind == "recursive":
        return text + "rec: &r [*r]\n", kind
    # structural mutations on the parsed document
    if len(text) > 100_000 or "&a0" in text:
        return text, "none"  # already a hostile text: not parsed here
    try:
        doc = yaml.safe_load(text)
        nodes = doc.get("nodes") or {}
        ids = list(nodes)
    except (yaml.YAMLError, AttributeError, TypeError, RecursionError):
        return text, "none"
    if not ids or not isinstance(nodes, dict) or not isinstance(nodes[ids[0]], dict):
        return text, "none"
    nid = rng.choice(ids)
    node = nodes[nid]
    if not isinstance(node, dict):
        return text, "none"
    if kind == "param":
        params = node.setdefault("params", {}) or {}
        node["params"] = params
        names = list(params) or ["path", "width", "sigma", "samples"]
        params[rng.choice(names)] = rng.choice(HOSTILE)
    elif kind == "drop_node":
        del nodes[nid]
    elif kind == "rewire":
        inputs = node.get("inputs") or {}
        if inputs:
            port = rng.choice(list(inputs))
            other = rng.choice(ids)
            inputs[port] = rng.choice([f"{other}.image", f"{other}.height", f"{nid}.image", f"{other}.nope",
                                       "x", 3, None, f"{other}.camera", f"{other}.light", f"{other}.mask"])
    elif kind == "retype":
        node["type"] = rng.choice(types + ["pixgraph.Nope", "", "os.system"])
    elif kind == "extra_key":
        node[rng.choice(["settings", "params", "extra", "inputs"])] = rng.choice(HOSTILE)
    elif kind == "swap_params" and len(ids) > 1:
        other = nodes[rng.choice(ids)]
        node["params"], other["params"] = other.get("params"), node.get("params")
    try:
        return yaml.safe_dump(doc, sort_keys=False, allow_unicode=True), kind
    except (ValueError, yaml.YAMLError, RecursionError):
        return text, "none"


def _param_changes(original: str, mutant: str) -> list[tuple[str, str, object]] | None:
    """[(node, param, new value)] when the mutant differs from the original only
    in param values (same nodes, types, inputs, outputs); else None."""
    try:
        a, b = yaml.safe_load(original), yaml.safe_load(mutant)
        if not isinstance(b, dict) or {k: v for k, v in a.items() if k != "nodes"} != \
                {k: v for k, v in b.items() if k != "nodes"} or set(a["nodes"]) != set(b["nodes"]):
            return None
        changes = []
        for nid, na in a["nodes"].items():
            nb = b["nodes"][nid]
            if not isinstance(nb, dict) or {k: v for k, v in na.items() if k != "params"} != \
                    {k: v for k, v in nb.items() if k != "params"}:
                return None
            pa, pb = na.get("params") or {}, nb.get("params") or {}
            if set(pa) - set(pb):
                return None
            changes += [(nid, k, pb[k]) for k in pb if pa.get(k, object()) != pb[k]]
        return changes
    except Exception:  # noqa: BLE001 - anything unparsable is not "only param changes"
        return None


def _only_valid_param_changes(original: str, mutant: str) -> bool:
    """The mutant only sets params to values their nodes declare valid."""
    from pixgraph.registry import Registry

    changes = _param_changes(original, mutant)
    if not changes:
        return False
    reg = Registry.discover()
    nodes = yaml.safe_load(original)["nodes"]
    for nid, pname, value in changes:
        p = reg.get(nodes[nid]["type"]).param(pname)
        try:
            p.coerce(value)
        except Exception:  # noqa: BLE001 - ParamError and friends: an invalid value
            return False
    return True


WORKER = r"""
import io, json, os, resource, sys, time, traceback, contextlib
resource.setrlimit(resource.RLIMIT_DATA, ({mem}, {mem}))
from pixgraph.cli import main
for line in sys.stdin:
    case = json.loads(line)
    err, out = io.StringIO(), io.StringIO()
    t0 = time.perf_counter()
    escaped = None
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        try:
            rc = main(case["argv"])
        except BaseException as e:
            rc, escaped = -1, traceback.format_exc()
    print(json.dumps({{"rc": rc, "s": time.perf_counter() - t0, "err": err.getvalue()[-100000:],
                      "escaped": escaped}}), flush=True)
"""


class Worker:
    def __init__(self):
        env = {**os.environ, "OMP_NUM_THREADS": "1", "POCL_MAX_PTHREAD_COUNT": "1", "PIXGRAPH_DISK_CACHE": "",
               "MKL_NUM_THREADS": "1"}
        self.p = subprocess.Popen([sys.executable, "-c", WORKER.format(mem=WORKER_MEMORY_BYTES)],
                                  stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                                  text=True, env=env, cwd=ROOT)

    def run(self, argv: list[str], timeout: float) -> dict:
        self.p.stdin.write(json.dumps({"argv": argv}) + "\n")
        self.p.stdin.flush()
        ready, _, _ = select.select([self.p.stdout], [], [], timeout)
        if not ready:
            self.kill()
            return {"rc": "timeout", "s": timeout, "err": "", "escaped": None}
        line = self.p.stdout.readline()
        if not line:
            code = self.p.wait()
            return {"rc": f"died({code})", "s": 0.0, "err": "", "escaped": None}
        return json.loads(line)

    def kill(self):
        with contextlib.suppress(ProcessLookupError):
            self.p.kill()
        self.p.wait()

    def alive(self) -> bool:
        return self.p.poll() is None


def fuzz(cases: int, seed: int, workdir: str, timeout: float = CASE_TIMEOUT_S, log=None) -> dict:
    """Run ``cases`` mutants; returns counts and the failing cases."""
    rng = random.Random(seed)
    job = os.path.join(workdir, "graphs")
    shutil.copytree(GRAPHS, job, dirs_exist_ok=True)
    sources, types = examples(), _node_types()
    outcomes: collections.Counter = collections.Counter()
    failures, slow_valid, slowest = [], [], 0.0
    worker = Worker()
    t_start = time.perf_counter()
    try:
        for i in range(cases):
            name = rng.choice(sorted(sources))
            text, kind = mutate(sources[name], rng, types)
            path = os.path.join(job, f"fuzz_{i:04d}.yaml")
            with open(path, "w", encoding="utf-8", errors="surrogateescape") as f:
                f.write(text)
            argv = ["run", path, "-q", "--no-disk-cache"]
            if not worker.alive():
                worker = Worker()
            r = worker.run(argv, timeout)
            if not worker.alive():
                worker = Worker()
            lines = [ln for ln in r["err"].splitlines() if ln.strip()]
            problems = []
            if r["rc"] not in (0, 2):
                problems.append(f"exit {r['rc']}")
            if r["escaped"] or "Traceback" in r["err"]:
                problems.append("traceback")
            if r["rc"] == "timeout" and _only_valid_param_changes(sources[name], text):
                # a well-formed graph asking for much work within its nodes' declared
                # limits (say samples: 65536): reported, but not a failure to reject input
                outcomes["slow but valid"] += 1
                slow_valid.append({"case": i, "from": name, "changes": _param_changes(sources[name], text)})
                problems = [p for p in problems if p != "exit timeout"]
            elif r["s"] > timeout:
                problems.append("slow")
            if any(len(ln) > MAX_LINE for ln in lines):
                problems.append("long line")
            if r["rc"] == 2 and len(lines) != 1:
                problems.append(f"{len(lines)} error lines")
            slowest = max(slowest, float(r["s"]))
            outcomes[f"exit {r['rc']}"] += 1
            if problems:
                outcomes["failed"] += 1
                failures.append({"case": i, "from": name, "mutation": kind, "problems": problems,
                                 "stderr": r["err"][-600:], "file": path})
            if log is not None:
                log(f"{i} {name} {kind} rc={r['rc']} {r['s']:.2f}s {'; '.join(problems)}")
    finally:
        worker.kill()
    return {"cases": cases, "seed": seed, "outcomes": dict(outcomes), "failures": failures, "slow_valid": slow_valid,
            "slowest_s": round(slowest, 2), "total_s": round(time.perf_counter() - t_start, 1)}


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=100)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--workdir", default=None)
    ap.add_argument("-v", action="store_true")
    a = ap.parse_args()
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        res = fuzz(a.cases, a.seed, a.workdir or tmp, log=print if a.v else None)
    for f in res["failures"]:
        print(json.dumps(f)[:1500])
    print(json.dumps({k: v for k, v in res.items() if k != "failures"}))
