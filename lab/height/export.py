"""Ship a trained cutout-height model: copy ``RUN/best.pt`` to
``nodes/weights/cutout_height.pt`` and write its provenance ``cutout_height.json``.

    python -m pixgraph_lab.height.export --run runs/height --data data/height [--eval runs/height_eval]

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
    ap.add_argument("--run", required=True)
    ap.add_argument("--data", required=True)
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
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
