#!/usr/bin/env python3
"""Does serving HTTP change the real-time threads' wake-up latency?

Runs `vigil demo` alternately without HTTP and with `--http` under load (a Prometheus-like scraper
at 10 Hz asking for OpenMetrics with gzip, and the dashboard open: headless Chromium on `/`, or
with --dashboard simulated a client making the page's requests), and compares the p99 wake-up
latency of the demo's 1 kHz SCHED_FIFO components from the final JSON reports. One run, rounds
alternated (A B A B ...) so that drift of a shared machine hits both sides.

    benches/export/http_load.py --vigil build/release/apps/vigil/vigil [--duration 20]
        [--rounds 2] [--dashboard browser|simulated|none] [--out DIR]

Prints a Markdown table (for docs/performance.md) and writes it to DIR/http_load.md.
"""
import argparse
import gzip
import json
import os
import re
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request

# The demo's 1 kHz SCHED_FIFO components that keep running (the encoder stops at ~4 s).
FIFO_1KHZ = ["motor_left", "motor_right", "logger", "can_io"]


def run_demo(vigil, duration, json_path, http, dashboard, stats):
    cmd = [vigil, "demo", "--duration", str(duration), "--no-live", "--json", json_path]
    if http:
        cmd += ["--http", "127.0.0.1:0"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    port = None
    stop = threading.Event()
    workers = []
    browser = None
    lines = []
    for line in proc.stdout:
        lines.append(line)
        m = re.search(r"HTTP on http://[^ ]*:(\d+)/", line)
        if m:
            port = int(m.group(1))
        if not http or port is not None or "running" in line:
            break
    if http and port is None:
        proc.kill()
        sys.exit("the demo did not announce its HTTP port:\n" + "".join(lines))
    def drain():
        for x in proc.stdout:
            lines.append(x)
            if x.startswith(("Stopped after", "Interrupted after")):
                stop.set()  # the demo is shutting down: stop loading it
    threading.Thread(target=drain, daemon=True).start()

    # The load stops a second before the demo does: requests during its shutdown would fail.
    load_end = time.monotonic() + duration - 1.0

    def poll(path, hz, headers):
        base = f"http://127.0.0.1:{port}"
        period = 1.0 / hz
        nxt = time.monotonic()
        while not stop.is_set() and time.monotonic() < load_end:
            try:
                req = urllib.request.Request(base + path, headers=headers)
                with urllib.request.urlopen(req, timeout=5) as r:
                    body = r.read()
                    if r.headers.get("Content-Encoding") == "gzip":
                        body = gzip.decompress(body)
                stats["requests"] += 1
                stats["bytes"] += len(body)
            except Exception:  # noqa: BLE001 - counted
                stats["errors"] += 1
            nxt += period
            stop.wait(max(0.0, nxt - time.monotonic()))

    if http:
        om = {"Accept": "application/openmetrics-text;version=1.0.0,text/plain;version=0.0.4;q=0.5",
              "Accept-Encoding": "gzip"}
        workers.append(threading.Thread(target=poll, args=("/metrics", 10, om), daemon=True))
        if dashboard == "simulated":
            for path, hz in (("/api/v1/reports", 2), ("/api/v1/histograms", 1),
                             ("/api/v1/history", 1)):
                workers.append(threading.Thread(target=poll, args=(path, hz, {}), daemon=True))
        elif dashboard == "browser":
            chromium = shutil.which("chromium") or shutil.which("chromium-browser")
            profile = tempfile.mkdtemp(prefix="vigil-load-")
            browser = subprocess.Popen(
                [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                 "--no-first-run", f"--user-data-dir={profile}", "--remote-debugging-port=0",
                 f"http://127.0.0.1:{port}/"],
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        for w in workers:
            w.start()
    rc = proc.wait(timeout=duration + 60)
    stop.set()
    for w in workers:
        w.join(10)
    if browser is not None:
        browser.send_signal(signal.SIGTERM)
        try:
            browser.wait(10)
        except subprocess.TimeoutExpired:
            browser.kill()
    if rc != 0:
        sys.exit(f"vigil demo exited with {rc}:\n" + "".join(lines[-20:]))
    with open(json_path) as f:
        doc = json.load(f)
    return {c["name"]: c["timing"]["latency_ns"]["p99"] for c in doc["components"]
            if c["name"] in FIFO_1KHZ}


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--vigil", required=True)
    p.add_argument("--duration", type=float, default=20)
    p.add_argument("--rounds", type=int, default=2)
    p.add_argument("--dashboard", choices=["browser", "simulated", "none"], default=None)
    p.add_argument("--out", default=".")
    a = p.parse_args()
    dashboard = a.dashboard or ("browser" if shutil.which("chromium") else "simulated")
    os.makedirs(a.out, exist_ok=True)
    base, load = {n: [] for n in FIFO_1KHZ}, {n: [] for n in FIFO_1KHZ}
    stats = {"requests": 0, "bytes": 0, "errors": 0}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(a.rounds):
            for side, http in (("without", False), ("with", True)):
                print(f"round {r + 1}/{a.rounds}: {side} HTTP load ({a.duration:.0f} s)", flush=True)
                p99 = run_demo(a.vigil, a.duration, os.path.join(tmp, f"{side}{r}.json"), http,
                               dashboard, stats)
                for n, v in p99.items():
                    (load if http else base)[n].append(v)
    rows = []
    ratios = []
    for n in FIFO_1KHZ:
        b, l = statistics.median(base[n]), statistics.median(load[n])
        ratio = l / b if b else float("nan")
        ratios.append(ratio)
        rows.append(f"| {n} | {b / 1e3:.1f} | {l / 1e3:.1f} | {ratio:.2f} |")
    table = "\n".join([
        f"Wake-up latency p99 of the demo's 1 kHz SCHED_FIFO components, {a.rounds} alternated "
        f"rounds of {a.duration:.0f} s per side (median of rounds). Load: /metrics at 10 Hz "
        f"(OpenMetrics, gzip) and the dashboard ({dashboard}); {stats['requests']} requests, "
        f"{stats['bytes'] / 1e6:.1f} MB, {stats['errors']} errors.",
        "",
        "| component | p99 without HTTP (us) | p99 with HTTP load (us) | ratio |",
        "| --- | --- | --- | --- |",
        *rows,
        f"| **median ratio** | | | **{statistics.median(ratios):.2f}** |",
    ])
    print()
    print(table)
    with open(os.path.join(a.out, "http_load.md"), "w") as f:
        f.write(table + "\n")


if __name__ == "__main__":
    main()
