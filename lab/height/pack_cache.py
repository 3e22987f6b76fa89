"""Pack the training script's crop caches (``DATA/cache_{split}_{size}.npz``,
see ``train.load_split``) small enough to travel to another machine, and unpack
them there bit for bit.

The caches hold float16 crops; their two bytes are split into two planes
("byte shuffle": the high bytes of neighbouring pixels are alike) and each
plane is LZMA-compressed: data/hsnap's four caches, 421 MB, pack to 57 MB (7.3x). ``unpack`` writes
the cache file back unchanged and an empty placeholder per sample file
(``SPLIT/00000.npz`` ...) where no file of that name is (a real sample stays),
which is all ``load_split`` looks at when its cache matches. ``unpack --check`` compares every array with the original caches.

    python -m pixgraph_lab.height.pack_cache pack --data data/hsnap --splits train,train_organic,val,val_organic --size 64 --out PACKDIR
    python -m pixgraph_lab.height.pack_cache unpack --pack PACKDIR --data DATA [--check data/hsnap]
"""
from __future__ import annotations

import argparse
import json
import lzma
import os
import re

import numpy as np

#: the sample file names ``train.load_split`` reads (``SPLIT/NNNNN.npz``)
SAMPLE = re.compile(r"[0-9]{5}\.npz")


def _pack_array(a: np.ndarray) -> dict:
    """A dict of plain arrays holding ``a`` losslessly (float16 shuffled + LZMA)."""
    a = np.array(a, order="C", copy=True)  # (ascontiguousarray would make a 0-d array 1-d)
    if a.dtype.kind in "fiu":
        raw = a.reshape(-1).view(np.uint8).reshape(-1, a.dtype.itemsize).T.copy().tobytes()
        return {"kind": "num", "dtype": a.dtype.str, "shape": list(a.shape),
                "data": np.frombuffer(lzma.compress(raw, preset=9), np.uint8)}
    return {"kind": "str", "dtype": a.dtype.str, "shape": list(a.shape),
            "data": np.frombuffer(lzma.compress(json.dumps(a.tolist()).encode(), preset=9), np.uint8)}


def _unpack_array(spec: dict, data: np.ndarray) -> np.ndarray:
    raw = lzma.decompress(data.tobytes())
    dt = np.dtype(spec["dtype"])
    if spec["kind"] == "num":
        planes = np.frombuffer(raw, np.uint8).reshape(dt.itemsize, -1)
        return planes.T.copy().view(dt).reshape(spec["shape"])
    return np.array(json.loads(raw.decode()), dtype=dt).reshape(spec["shape"])


def pack(data: str, splits, size: int, out: str) -> None:
    os.makedirs(out, exist_ok=True)
    for split in splits:
        src = os.path.join(data, f"cache_{split}_{size}.npz")
        with np.load(src, allow_pickle=False) as z:
            specs, arrays = {}, {}
            if "spec" in z.files:
                raise SystemExit(f"{src}: an array named 'spec' (the pack's own) cannot travel")
            for k in z.files:           # every array: train.load_split's x t w bh n meta names, and any other
                p = _pack_array(z[k])
                arrays[k] = p.pop("data")
                specs[k] = p
        np.savez(os.path.join(out, f"{split}_{size}.npz"), spec=json.dumps(specs), **arrays)
        print(f"{split}: {os.path.getsize(src) / 1e6:.1f} MB -> "
              f"{os.path.getsize(os.path.join(out, f'{split}_{size}.npz')) / 1e6:.1f} MB", flush=True)


def unpack(pack_dir: str, data: str, check: str | None = None) -> None:
    for name in sorted(os.listdir(pack_dir)):
        if not name.endswith(".npz"):
            continue
        split, size = name[:-4].rsplit("_", 1)
        with np.load(os.path.join(pack_dir, name), allow_pickle=False) as z:
            specs = json.loads(str(z["spec"]))
            arrays = {k: _unpack_array(specs[k], z[k]) for k in specs}
        names = [str(s) for s in arrays["names"]] if "names" in arrays else \
            [f"{i:05d}.npz" for i in range(int(arrays["n"]))]
        bad = [nm for nm in names if not SAMPLE.fullmatch(nm)]
        if bad:     # load_split reads only NNNNN.npz; a path such as ../x would land elsewhere
            raise SystemExit(f"{name}: sample names {bad[:3]} are not NNNNN.npz: nothing unpacked")
        os.makedirs(os.path.join(data, split), exist_ok=True)
        for nm in names:
            try:    # a placeholder only where no file is: a real sample there stays as it is
                open(os.path.join(data, split, nm), "xb").close()
            except FileExistsError:
                pass
        if check:       # before writing: unpacked over the checked caches, it would compare them with themselves
            with np.load(os.path.join(check, f"cache_{split}_{size}.npz"), allow_pickle=False) as z0:
                if sorted(z0.files) != sorted(arrays):
                    raise SystemExit(f"{name}: arrays {sorted(arrays)} differ from {check}'s {sorted(z0.files)}")
                for k in z0.files:
                    a0, a1 = z0[k], arrays[k]
                    if a0.dtype != a1.dtype or a0.shape != a1.shape or a0.tobytes() != a1.tobytes():
                        raise SystemExit(f"{name}: array {k} differs from {check}")
        np.savez(os.path.join(data, f"cache_{split}_{size}.npz"), **arrays)
        print(f"{split}: {len(names)} samples{' (checked: identical)' if check else ''}", flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pixgraph_lab.height.pack_cache", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser("pack")
    p.add_argument("--data", required=True)
    p.add_argument("--splits", required=True)
    p.add_argument("--size", type=int, default=64)
    p.add_argument("--out", required=True)
    u = sub.add_parser("unpack")
    u.add_argument("--pack", required=True)
    u.add_argument("--data", required=True)
    u.add_argument("--check", default=None)
    a = ap.parse_args(argv)
    if a.cmd == "pack":
        pack(a.data, a.splits.split(","), a.size, a.out)
    else:
        unpack(a.pack, a.data, a.check)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
