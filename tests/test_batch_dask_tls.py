"""The Dask executor's local cluster is closed to other processes: its scheduler
listens on a port of 127.0.0.1, and over plain TCP any process of any user of the
machine connected and ran code in the batch's workers (``client.run``). It speaks TLS
now with certificates made for it alone (``Security.temporary``): a client without
them is refused, at the TLS handshake. Their HTTP servers (plain HTTP, whatever
``dashboard_address`` says) serve no routes: their /info pages gave any local user
the workers' logs and call stacks. pixgraph_batch/executors.py."""
import os
import socket
import ssl
import urllib.error
import urllib.request

import pytest

from pixgraph.cli import main

pytest.importorskip("distributed", reason="the batch extra (dask.distributed) is part of ./setup.sh test")

GRAPH = ("pixgraph: 1\nnodes:\n  c: {type: pixgraph.Constant, params: {width: 8, height: 8, "
         "color: [0.2, 0.2, 0.2, 1]}}\noutputs: {final: c.image}\n")


def _intrude(address: str) -> str:
    """What a process without the cluster's certificates gets from ``address``."""
    from distributed import Client

    host, port = address.split("://", 1)[1].rsplit(":", 1)
    try:
        c = Client(f"tcp://{host}:{port}", timeout=15)
    except Exception as e:                                # noqa: BLE001 - any refusal
        plain = f"refused ({type(e).__name__})"
    else:
        plain = "ran: " + str(c.run(os.getpid))
        c.close()
    ctx = ssl.create_default_context()
    ctx.check_hostname, ctx.verify_mode = False, ssl.CERT_NONE
    try:
        with socket.create_connection((host, int(port)), timeout=15) as raw, ctx.wrap_socket(raw) as tls:
            tls.sendall(b"\0" * 16)
            tls.recv(16)
        raw_tls = "handshake done"
    except (ssl.SSLError, OSError) as e:
        raw_tls = f"refused ({type(e).__name__})"
    return f"plain TCP: {plain}; TLS without a certificate: {raw_tls}"


def test_another_process_cannot_run_code_in_the_local_clusters_workers(tmp_path, monkeypatch):
    import distributed

    seen = []
    real = distributed.Client

    def client(*args, **kwargs):
        c = real(*args, **kwargs)
        if args and hasattr(args[0], "scheduler_address") and not seen:
            seen.append((args[0].scheduler_address, _intrude(args[0].scheduler_address)))
        return c

    def http(c) -> list:
        """What a process of another user reads from the cluster's plain-HTTP servers
        (the scheduler's and each worker's): their logs and call stacks before."""
        ports = _ports(c.cluster.scheduler.http_server)
        ports += [w["services"]["dashboard"] for w in c.scheduler_info()["workers"].values()]
        got = []
        for port in ports:
            for path in ("/info/main/workers.html", "/info/logs/x.html", "/json/identity.json", "/health"):
                try:
                    with urllib.request.urlopen(f"http://127.0.0.1:{port}{path}", timeout=15) as r:
                        got.append(f"{port}{path}: {r.status} {r.read()[:80]!r}")
                except urllib.error.HTTPError as e:
                    got.append(f"{port}{path}: {e.code}")
        return got

    def client_http(*args, **kwargs):
        c = client(*args, **kwargs)
        if args and hasattr(args[0], "scheduler_address") and not pages:
            pages.extend(http(c))
        return c

    pages: list = []
    monkeypatch.setattr(distributed, "Client", client_http)
    (tmp_path / "g.yaml").write_text(GRAPH)
    (tmp_path / "rows.csv").write_text("id,c.width\n" + "".join(f"r{i},{8 + i}\n" for i in range(4)))
    assert main(["batch", str(tmp_path / "g.yaml"), str(tmp_path / "rows.csv"), "--dask-local", "1",
                 "--no-disk-cache", "-o", f"final={tmp_path}/out/{{row}}.png"]) == 0
    assert len(os.listdir(tmp_path / "out")) == 8                       # the batch itself ran
    [(address, got)] = seen
    print(address, got)
    assert address.startswith("tls://127.0.0.1:"), address
    assert "ran:" not in got and "handshake done" not in got, got
    assert len(pages) >= 8 and all(p.endswith(": 404") for p in pages), pages     # no route served
    # (before: workers.html, identity.json and /health answered 200 to anyone)


def _ports(server) -> list:
    return [s.getsockname()[1] for s in server._sockets.values()]
