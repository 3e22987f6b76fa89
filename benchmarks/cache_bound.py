"""How far the disk cache's byte bound is exceeded with several writer processes.

N writers put ~100 kB entries into one cache folder with a 1 MB limit while a
sampler scans the folder (without the lock) as fast as it can. Reports the largest
committed size any scan saw and the final size, as a ratio to the limit. A
measurement of a bound, not of speed::

    python benchmarks/cache_bound.py --writers 2 --entries 200
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time

from _machine import cpu_model

WRITER = """
import numpy as np
from pixgraph.cache import DiskCache
d = DiskCache({disk!r}, {limit})
for i in range({n}):
    d.put("%02x" % (i % 256) + "%062x" % (i * 7919 + {seed}), {{"a": np.full(25_000, i, np.float32)}})
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--writers", type=int, default=2)
    ap.add_argument("--entries", type=int, default=200)
    ap.add_argument("--limit", type=int, default=1_000_000)
    a = ap.parse_args()
    from pixgraph.cache import DiskCache

    with tempfile.TemporaryDirectory() as disk:
        procs = [subprocess.Popen([sys.executable, "-c", WRITER.format(disk=disk, limit=a.limit, n=a.entries,
                                                                       seed=w)]) for w in range(a.writers)]
        d = DiskCache(disk, a.limit)
        worst, scans = 0, 0
        while any(p.poll() is None for p in procs):
            worst = max(worst, sum(e[1] for e in d.entries()))
            scans += 1
            time.sleep(0.001)
        final = d.stats()
        entry = max((e[1] for e in d.entries()), default=0)
    print(json.dumps({"writers": a.writers, "entries_each": a.entries, "limit": a.limit, "entry_bytes": entry,
                      "scans": scans, "max_seen_ratio": round(worst / a.limit, 3),
                      "max_seen_over_limit_in_entries": round(max(0, worst - a.limit) / max(entry, 1), 2),
                      "final_ratio": round(final["bytes"] / a.limit, 3), "temporaries_left": final["temporaries"],
                      "machine": cpu_model()}))


if __name__ == "__main__":
    main()
