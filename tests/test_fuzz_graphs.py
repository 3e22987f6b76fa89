"""Fuzzing the graph files: mutants of the example graphs (hostile params, aliases
that expand to billions of nodes, deep nesting, cut and garbled text, retyped and
rewired nodes, hostile paths) are all either run or refused as bad input: no
traceback, no exit 1, nothing over 30 s, one error line of at most 300 characters.
A mutant that only sets params to values their nodes declare valid and still takes
over 30 s (``samples: 65536`` on a soft shadow) is a valid, expensive graph: it is
counted and printed as "slow but valid", not failed.
Seeded; about a minute by default, a longer run under ``-m slow``."""
import pytest

from fuzz_graphs import fuzz


def _check(res):
    lines = [f"case {f['case']} ({f['from']}, {f['mutation']}): {f['problems']}: {f['stderr'][-300:]!r}"
             for f in res["failures"]]
    assert not res["failures"], "\n".join(lines[:20])
    assert sum(v for k, v in res["outcomes"].items() if k.startswith("exit")) == res["cases"]
    for case in res["slow_valid"]:  # valid graphs that ask for a lot of work: shown, not failed
        print(f"slow but valid (over 30 s within declared param limits): {case}")
    # the mutants exercise both paths: most are refused, some still run
    assert res["outcomes"].get("exit 2", 0) > res["cases"] // 2 and res["outcomes"].get("exit 0", 0) > 0


def test_fuzzed_example_graphs_fail_cleanly(tmp_path):
    _check(fuzz(cases=200, seed=11, workdir=str(tmp_path)))


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_fuzzed_example_graphs_fail_cleanly_long(tmp_path, seed):
    _check(fuzz(cases=1000, seed=seed, workdir=str(tmp_path)))
