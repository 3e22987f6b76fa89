"""Ship a trained cutout-height model: copy ``RUN/best.pt`` to
``nodes/weights/cutout_height.pt`` and write its provenance ``cutout_height.json``.

    python -m pixgraph_lab.height.export --run runs/height --data data/height [--eval runs/height_eval]
    python -m pixgraph_lab.height.export --npz      # only the numpy weights, from the shipped .pt

Both also write ``cutout_height.npz``, the weights the numpy network reads
(``pixgraph_nodes.ops.height_net``: learned heights without torch): the
checkpoint's state dict unchanged (float16, as trained and shipped; each
BatchNorm is folded into its convolution at load, in float32, the same
arithmetic as torch's folded model), its config and the .pt's sha256 (a .pt
replaced without a new .npz is refused when loaded). The provenance gets a
``numpy_weights`` entry.

The provenance records the training command, seed, steps, time, validation curve
and best validation MAE (from ``RUN/train.json`` or, for a run still going, from
the checkpoint), the generator commands and sample counts of the data, and the
evaluation report when ``--eval`` is given.
"""
from __future__ import annotations

import argparse
import glob
import json
import os
import pathlib
import shutil


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--run", default=None, help="the training run whose best.pt is shipped")
    ap.add_argument("--data", default=None)
    ap.add_argument("--npz", action="store_true",
                    help="only write cutout_height.npz (the numpy network's weights) from the shipped .pt "
                         "and record it in cutout_height.json; --run / --data not needed")
    ap.add_argument("--eval", default=None, help="folder with report.md of pixgraph_lab.height.evaluate")
    ap.add_argument("--command", default=None, help="the training command, when train.json is missing")
    ap.add_argument("--splits", default="train,train_bench,val,val_bench,test",
                    help="sub-folders of --data to record (sample counts, generator commands)")
    ap.add_argument("--previous-run", action="append", default=[],
                    help="a run this one was initialised from (--init): its command, steps and time "
                         "are recorded too (repeatable, oldest first)")
    a = ap.parse_args(argv)
    import torch
    from pixgraph_nodes.ops.learned_height import WEIGHTS
    if a.npz:
        write_numpy_weights(WEIGHTS)
        return 0
    if not a.run or not a.data:
        ap.error("--run and --data are required (or --npz alone)")
    ck = torch.load(os.path.join(a.run, "best.pt"), map_location="cpu", weights_only=True)
    st = ck["state"]
    info = {}
    tj = os.path.join(a.run, "train.json")
    if os.path.exists(tj):
        info = json.load(open(tj))
    data = {}
    for split in a.splits.split(","):
        cfgs = [json.load(open(p)) for p in sorted(glob.glob(os.path.join(a.data, split, "config_*.json")))]
        data[split] = {"samples": len(glob.glob(os.path.join(a.data, split, "[0-9]" * 5 + ".npz"))),
                       "generator": [c["command"] for c in cfgs],
                       "seconds_per_sample": [round(c["seconds"] / max(c["new_samples"], 1), 3)
                                              for c in cfgs if "new_samples" in c]}
    prov = {
        "command": info.get("command", a.command),
        "seed": info.get("seed", 0),
        "config": json.loads(ck["config"]),
        "steps": st["step"], "seconds": round(st["seconds"], 1),
        "best_val_mae_px": st["best"],
        "curve": st["curve"],
        "data": data,
        "train_device": info.get("device", "cpu"), "threads": info.get("threads", 1),
        "dtype": "float16 state dict (loaded as float32)",
    }
    prev = []
    for r in a.previous_run:
        pj = json.load(open(os.path.join(r, "train.json")))
        prev.append({k: pj.get(k) for k in ("command", "steps", "seconds", "best_val_mae_px", "train_samples")})
    if prev:
        prov["previous_runs"] = prev
    if a.eval:
        prov["evaluation"] = pathlib.Path(a.eval, "report.md").read_text()
    WEIGHTS.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(os.path.join(a.run, "best.pt"), WEIGHTS)
    WEIGHTS.with_suffix(".json").write_text(json.dumps(prov, indent=1) + "\n")
    print(f"{WEIGHTS} ({WEIGHTS.stat().st_size} bytes), step {st['step']}, best val MAE {st['best']:.2f} px")
    write_numpy_weights(WEIGHTS)
    return 0


def write_numpy_weights(pt: pathlib.Path) -> pathlib.Path:
    """``pt``'s numpy weights (``height_net.write_npz``) beside it, recorded in its
    provenance JSON (``numpy_weights``)."""
    import torch
    from pixgraph_nodes.ops import height_net
    ck = torch.load(pt, map_location="cpu", weights_only=True)
    state = {k: v.numpy() for k, v in ck["model"].items()}
    digest = height_net.pt_digest(pt)
    out = height_net.write_npz(state, ck["config"], pt.with_suffix(".npz"), digest)
    dtypes = sorted({str(v.dtype) for k, v in state.items() if not k.endswith("num_batches_tracked")})
    pj = pt.with_suffix(".json")
    if pj.exists():
        prov = json.loads(pj.read_text())
        # the checkpoint's config, inference rules included (a study's --write changes them in the .pt)
        prov["config"] = json.loads(ck["config"]) if isinstance(ck["config"], str) else ck["config"]
        prov["numpy_weights"] = {
            "file": out.name, "bytes": out.stat().st_size, "source_sha256": digest,
            "dtype": ", ".join(dtypes) + " (the checkpoint's own values; BatchNorm folded at load in float32)",
            "command": "python -m pixgraph_lab.height.export --npz"}
        pj.write_text(json.dumps(prov, indent=1) + "\n")
    print(f"{out} ({out.stat().st_size} bytes, {', '.join(dtypes)}) from {pt.name} (sha256 {digest[:12]})")
    return out


if __name__ == "__main__":
    raise SystemExit(main())
