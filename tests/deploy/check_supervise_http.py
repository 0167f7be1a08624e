#!/usr/bin/env python3
"""`vigil supervise --http`: the daemon serves its reports and /metrics while it runs (issue 17).

    check_supervise_http.py VIGIL
"""
import os
import socket
import subprocess
import sys
import time
import urllib.request


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def get(url):
    with urllib.request.urlopen(url, timeout=5) as r:
        return r.status, r.read().decode()


def main():
    vigil = sys.argv[1]
    port = free_port()
    name = f"cihttp{os.getpid()}"
    proc = subprocess.Popen([vigil, "supervise", "--name", name, "--duration", "5", "--no-live",
                             "--http", f"127.0.0.1:{port}"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    base = f"http://127.0.0.1:{port}"
    reports = metrics = None
    deadline = time.monotonic() + 4
    while time.monotonic() < deadline and reports is None:
        time.sleep(0.2)
        try:
            status, body = get(base + "/api/v1/reports")
            if status == 200 and "vigil.supervise" in body:
                reports = body
                metrics = get(base + "/metrics")[1]
        except OSError:
            pass
    out, _ = proc.communicate(timeout=30)
    print(out)
    if reports is None:
        print("FAIL: /api/v1/reports never showed the daemon's own report", file=sys.stderr)
        return 1
    if "vigil_component_status" not in metrics:
        print("FAIL: /metrics has no vigil_component_status", file=sys.stderr)
        return 1
    if f"127.0.0.1:{port}" not in out:
        print("FAIL: the daemon did not say where it listens", file=sys.stderr)
        return 1
    if proc.returncode != 0:
        print(f"FAIL: vigil supervise exited {proc.returncode}", file=sys.stderr)
        return 1
    print("supervise --http: reports and /metrics served")
    return 0


if __name__ == "__main__":
    sys.exit(main())
