#!/usr/bin/env python3
"""Soak test of `vigil demo` (issue 20; figures in docs/performance.md).

    soak.py VIGIL --duration S [--warmup W] [--workdir DIR] [--config FILE] [--max-growth-kib K]

Runs `vigil demo --duration S --json DIR/final.json` with its live view on a pipe (one status
table per second), samples the resident memory (VmRSS of /proc/PID/status) every 5 s, and checks:

1. memory: VmRSS at the end (sampled within the last seconds of the run) minus VmRSS after the
   warm-up W (default: 15 s, or 60 s for runs of 10 minutes and more) is below K KiB (1024);
2. drops: in the final JSON, a component dropped messages only if its port filled up (high-water
   mark == capacity): no drop that the port size does not explain;
3. status changes: every time a component is shown not OK, the view gives a cause (a message);
   the count of status changes per component is printed;
4. the demo exited 0 and wrote its final reports.

Prints the figures as one JSON line prefixed "soak:" (docs/performance.md) and exits 1 on any
failed check.
"""
import argparse
import json
import os
import re
import subprocess
import sys
import time


def vmrss_kib(pid):
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1])
    except OSError:
        return None
    return None




def parse_view(lines):
    """Per second: {component: (status, message)} from the live view's tables."""
    tables = []
    current = None
    for line in lines:
        if line.startswith("vigil demo — "):
            current = {}
            tables.append(current)
            continue
        if current is None or line.startswith("STATUS "):
            continue
        m = re.match(r"^(OK|WARN|ERROR|STALE)\s+(.{24}) (.*)$", line)
        if not m:
            continue
        status, name, rest = m.group(1), m.group(2).strip(), m.group(3)
        # Columns after the name: STATE CYCLES EXEC LAT OVERRUNS LOSSES MESSAGES; the message is
        # what follows the LOSSES column (two integers, then two spaces).
        msg = re.split(r"\s+\d+\s+\d+(?:\s{2}|$)", rest, maxsplit=1)
        message = msg[1].strip() if len(msg) > 1 else ""
        current[name] = (status, message)
    return tables


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("vigil")
    ap.add_argument("--duration", type=float, required=True)
    ap.add_argument("--warmup", type=float)
    ap.add_argument("--workdir", default="/tmp/vigil-soak")
    ap.add_argument("--config")
    ap.add_argument("--max-growth-kib", type=int, default=1024)
    a = ap.parse_args()
    warmup = a.warmup if a.warmup is not None else (60.0 if a.duration >= 600 else 15.0)
    os.makedirs(a.workdir, exist_ok=True)
    json_path = os.path.join(a.workdir, "final.json")
    view_path = os.path.join(a.workdir, "view.txt")
    if os.path.exists(json_path):
        os.remove(json_path)
    cmd = [a.vigil, "demo", "--duration", str(a.duration), "--json", json_path, "--color", "never"]
    if a.config:
        cmd += ["--config", a.config]
    start = time.monotonic()
    view = open(view_path, "w")
    proc = subprocess.Popen(cmd, stdout=view, stderr=subprocess.STDOUT)
    samples = []  # (seconds since start, VmRSS KiB)
    while proc.poll() is None:
        t = time.monotonic() - start
        rss = vmrss_kib(proc.pid)
        if rss is not None:
            samples.append((round(t, 1), rss))
        time.sleep(1.0 if t < warmup + 5 or t > a.duration - 10 else 5.0)
    rc = proc.returncode
    view.close()
    failures = []
    if rc != 0:
        failures.append(f"vigil demo exited {rc}")

    at_warmup = next((s for s in samples if s[0] >= warmup), None)
    in_run = [s for s in samples if s[0] <= a.duration]
    at_end = in_run[-1] if in_run else None
    growth = None
    if at_warmup and at_end and at_end[0] > at_warmup[0]:
        growth = at_end[1] - at_warmup[1]
        if growth >= a.max_growth_kib:
            failures.append(f"VmRSS grew {growth} KiB from {at_warmup} to {at_end} (limit {a.max_growth_kib})")
    else:
        failures.append(f"not enough memory samples: {samples[:3]}...{samples[-3:]}")

    drops = {}
    try:
        with open(json_path) as f:
            final = json.load(f)
        for c in final["components"]:
            if "fields" in c:
                continue  # a unit (a CAN node or group): no port of its own
            dropped = c["counters"]["dropped"]
            port = c.get("port", {})
            if dropped:
                drops[c["name"]] = dropped
                if port.get("capacity", 0) and port.get("high_water", 0) < port["capacity"]:
                    failures.append(f"{c['name']}: {dropped} dropped but the port never filled ({port})")
    except (OSError, ValueError, KeyError) as e:
        failures.append(f"final reports: {e}")
        final = None

    with open(view_path) as f:
        tables = parse_view(f.read().splitlines())
    changes = {}
    last = {}
    uncaused = []
    for i, table in enumerate(tables):
        for name, (status, message) in table.items():
            if name in last and last[name] != status:
                changes[name] = changes.get(name, 0) + 1
            last[name] = status
            if status != "OK" and not message:
                uncaused.append(f"{name} {status} at second {i + 1} without a message")
    if len(tables) < a.duration * 0.5:
        failures.append(f"only {len(tables)} live views in {a.duration} s")
    failures += uncaused[:10]

    figures = {
        "duration_s": a.duration,
        "warmup_s": warmup,
        "rss_kib_at_warmup": at_warmup[1] if at_warmup else None,
        "rss_kib_at_end": at_end[1] if at_end else None,
        "rss_growth_kib": growth,
        "rss_max_kib": max((s[1] for s in samples), default=None),
        "views": len(tables),
        "status_changes": changes,
        "dropped": drops,
        "final_status": {c["name"]: c["status"] for c in final["components"]} if final else None,
        "exit": rc,
    }
    print("soak: " + json.dumps(figures, sort_keys=True))
    with open(os.path.join(a.workdir, "rss.txt"), "w") as f:
        f.writelines(f"{t} {k}\n" for t, k in samples)
    if failures:
        print("soak: FAILED\n  " + "\n  ".join(failures))
        return 1
    print(f"soak: passed ({a.workdir})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
