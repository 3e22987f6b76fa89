"""Probe of issue 23's cache and file cases through the command line: for each case, the
exit code, the stderr lines and how many files changed (or how many output bytes differ
from a reference run). Run as root for the full-disk row (it mounts a 1 MiB tmpfs).

    python tools/probe_cache_files.py .      # ~40 s on 2 shared cores

Work folder: /tmp/files-probe/w (deleted first). The asserted versions of these cases are
in tests/test_security_cache.py and tests/test_security_paths.py."""
import hashlib, os, shutil, subprocess, sys, time
import numpy as np
REPO = sys.argv[1]
PIX = os.path.join(os.path.dirname(sys.executable), "pixgraph")
G = os.path.join(REPO, "graphs", "wall_corner_shadow.yaml")
W = "/tmp/files-probe/w"
shutil.rmtree(W, ignore_errors=True); os.makedirs(W)

def tree(root):
    out = {}
    for d, dirs, files in os.walk(root):
        for n in dirs + files:
            p = os.path.join(d, n); st = os.lstat(p)
            out[os.path.relpath(p, root)] = (st.st_mode, st.st_mtime_ns, hashlib.sha256(open(p, "rb").read()).hexdigest() if os.path.isfile(p) and not os.path.islink(p) else None)
    return out

def diff(a, b):
    return len(set(a) ^ set(b)) + sum(a[k] != b[k] for k in set(a) & set(b) if not os.path.isdir(k))

def run(*argv):
    p = subprocess.run([PIX, *argv], capture_output=True, text=True)
    return p.returncode, p.stderr.strip().splitlines()

def plant(root):
    os.makedirs(f"{root}/go/pkg/mod"); open(f"{root}/go/pkg/mod/x.txt", "w").write("go")
    os.makedirs(f"{root}/v1"); np.savez(f"{root}/v1/weights.npz", w=np.arange(3))
    os.makedirs(f"{root}/docs"); open(f"{root}/docs/.tmp-draft.txt", "w").write("draft")
    old = time.time() - 7200
    for d, _, fs in os.walk(root):
        for f in fs: os.utime(os.path.join(d, f), (old, old))

rows = []
# 1 foreign folder as --disk-cache: run, explain, cache stats, cache clear
shared = f"{W}/shared"; plant(shared); before = tree(shared)
for cmd in (["run", G, "-q", "--disk-cache", shared, "-o", f"final={W}/o1.png"], ["explain", G, "--disk-cache", shared],
            ["cache", "stats", "--disk-cache", shared], ["cache", "clear", "--disk-cache", shared]):
    rc, err = run(*cmd)
    rows.append((f"foreign folder: {cmd[0]} {cmd[1] if cmd[0]=='cache' else ''}", rc, len(err), diff(before, tree(shared))))
# 2 pixgraph's own cache with others' files inside: run, then cache clear
own = f"{W}/own"
rc, _ = run("run", G, "-q", "--disk-cache", own, "-o", f"final={W}/ref.png")
plant(own); before = {k: v for k, v in tree(own).items() if not (k.endswith(".pxc") or k.startswith("records/") or len(k) == 2 or k == "records")}
rc, err = run("cache", "clear", "--disk-cache", own)
after = tree(own)
rows.append(("own cache + others' files: cache clear", rc, len(err), sum(k not in after or after[k] != v for k, v in before.items())))
rows.append(("  entries left after clear", 0, 0, sum(k.endswith(".pxc") for k in after)))
# 3 full disk: 1 MiB tmpfs
mnt = f"{W}/tmpfs"; os.makedirs(mnt)
ok = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", mnt]).returncode == 0
if ok:
    rc, err = run("run", G, "-q", "--disk-cache", f"{mnt}/c", "-o", f"final={W}/o3.png")
    rows.append(("full disk (1 MiB tmpfs), example graph", rc, len(err), int(subprocess.run(["cmp", "-s", f"{W}/o3.png", f"{W}/ref.png"]).returncode != 0)))
    print("  stderr:", err)
    subprocess.run(["umount", "-l", mnt])
# 4 a directory at every entry's path
dc = f"{W}/dirs"
rc, _ = run("run", G, "-q", "--disk-cache", dc)
for d, _, fs in os.walk(dc):
    for f in fs:
        if f.endswith(".pxc"):
            p = os.path.join(d, f); os.remove(p); os.makedirs(p); open(os.path.join(p, "keep"), "w").write("k")
rc, err = run("run", G, "-q", "--disk-cache", dc, "-o", f"final={W}/o4.png")
rows.append(("a folder at every entry's path", rc, len(err), int(subprocess.run(["cmp", "-s", f"{W}/o4.png", f"{W}/ref.png"]).returncode != 0)))
# 5 --cache-bytes -1
rc, err = run("run", G, "-q", "--no-disk-cache", "--cache-bytes", "-1")
rows.append(("--cache-bytes -1", rc, len(err), 0)); print("  stderr:", err)
# 6 JPEG as the cutout
for cmd in ("run", "validate"):
    extra = ["--no-disk-cache"] if cmd == "run" else []
    rc, err = run(cmd, G, "-q", *extra, "--set", "cutout.path=assets/room_ground.jpg")
    rows.append((f"JPEG cutout: {cmd}", rc, len(err), 0)); print("  stderr:", err)
for r in rows:
    print(f"{r[0]:45s} rc={r[1]}  stderr lines={r[2]}  changed/differing={r[3]}")
