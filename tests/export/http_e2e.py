#!/usr/bin/env python3
"""End-to-end checks of `vigil demo --http`, run by CTest (tests/export/CMakeLists.txt).

    http_e2e.py CHECK --vigil PATH/TO/vigil --source SOURCE_DIR --out BUILD_DIR

CHECK is one of:
  promtool     `promtool check metrics` accepts the Prometheus 0.0.4 body
  openmetrics  prometheus_client's OpenMetrics parser accepts the OpenMetrics body
  reference    every metric of docs/reference/metrics.md is exposed, every exposed one documented
  chromium     headless Chromium shows every component with the JSON API's status; screenshot
  prometheus   a real Prometheus scrapes the demo: components, histogram_quantile, an alert,
               the exemplars (exemplar storage on): a worst cycle's, and the trace one names
  fleet        docs/fleet/: agent mode + remote write + the documented alerts, the Grafana JSON
  requests     bad requests get 4xx, 100 concurrent scrapers are served, slow clients are bounded,
               a second server on the port fails, the default listener is on 127.0.0.1 only
  module       the HTTP module (libvigil_http.so, with cpp-httplib and OpenSSL) is mapped only
               with --http; VIGIL_HTTP_MODULE naming a missing file or a library that is not
               the module stops the demo with an error naming it

A check whose tool is missing exits 77 (CTest: skipped) and says why. Every check is bounded in
time: the demo runs with --duration and is stopped with SIGINT (its Ctrl-C) when done.
"""
import argparse
import concurrent.futures
import html.parser
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import urllib.error
import urllib.parse
import urllib.request

SKIP = 77


def skip(reason):
    print(f"SKIP: {reason}")
    sys.exit(SKIP)


def fail(message):
    print(f"FAIL: {message}")
    sys.exit(1)


class Demo:
    """`vigil demo --http ADDR` in the background; knows its port once it announced it."""

    def __init__(self, vigil, listen="127.0.0.1:0", duration=30, extra=()):
        self.cmd = [vigil, "demo", "--duration", str(duration), "--no-live", "--http", listen,
                    *extra]
        self.proc = subprocess.Popen(self.cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                     text=True, bufsize=1)
        self.lines = []
        self.port = None
        self._announced = threading.Event()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        if not self._announced.wait(30):
            self.stop()
            fail("the demo did not announce its HTTP address:\n" + "".join(self.lines))
        if self.port is None:
            fail("the demo exited early:\n" + "".join(self.lines))

    def _read(self):
        for line in self.proc.stdout:
            self.lines.append(line)
            m = re.search(r"HTTP on http://[^ ]*:(\d+)/", line)
            if m and self.port is None:
                self.port = int(m.group(1))
                self._announced.set()
        self._announced.set()

    @property
    def base(self):
        return f"http://127.0.0.1:{self.port}"

    def get(self, path, headers=None, timeout=10):
        req = urllib.request.Request(self.base + path, headers=headers or {})
        with urllib.request.urlopen(req, timeout=timeout) as r:
            return r.status, dict(r.headers), r.read().decode("utf-8")

    def wait_healthy(self, timeout=20):
        end = time.time() + timeout
        while time.time() < end:
            try:
                status, _, _ = self.get("/healthz", timeout=2)
                if status == 200:
                    return
            except (urllib.error.URLError, ConnectionError, OSError):
                pass
            time.sleep(0.2)
        fail("/healthz never answered 200:\n" + "".join(self.lines))

    def stop(self):
        """Stops the demo with SIGINT (its Ctrl-C) and returns its exit code."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
        try:
            rc = self.proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            rc = self.proc.wait()
        self._reader.join(5)
        return rc

    def finish(self):
        rc = self.stop()
        if rc != 0:
            fail(f"the demo exited with {rc}:\n" + "".join(self.lines[-30:]))


OM_ACCEPT = ("application/openmetrics-text;version=1.0.0,application/openmetrics-text;"
             "version=0.0.1;q=0.75,text/plain;version=0.0.4;q=0.5,*/*;q=0.1")


def exposed_families(text):
    """Family names of a 0.0.4 body (from its TYPE lines)."""
    return {line.split()[2] for line in text.splitlines() if line.startswith("# TYPE ")}


# --- checks ---------------------------------------------------------------------------------------

def check_promtool(args):
    promtool = shutil.which("promtool")
    if not promtool:
        skip("promtool not found (Debian package prometheus)")
    demo = Demo(args.vigil, duration=20)
    demo.wait_healthy()
    time.sleep(2)
    status, headers, body = demo.get("/metrics")
    demo.finish()
    if status != 200 or not headers.get("Content-Type", "").startswith("text/plain; version=0.0.4"):
        fail(f"/metrics: {status} {headers.get('Content-Type')}")
    r = subprocess.run([promtool, "check", "metrics"], input=body, text=True,
                       capture_output=True, timeout=60)
    print(r.stdout + r.stderr)
    if r.returncode != 0 or r.stdout.strip() or r.stderr.strip():
        fail(f"promtool check metrics: exit {r.returncode}")
    print(f"promtool: {len(body)} bytes, {len(exposed_families(body))} families, no problem")


def check_openmetrics(args):
    try:
        from prometheus_client.openmetrics.parser import text_string_to_metric_families
    except ImportError:
        skip(f"{sys.executable} has no prometheus_client (Debian package python3-prometheus-client)")
    demo = Demo(args.vigil, duration=20)
    demo.wait_healthy()
    time.sleep(2)
    status, headers, body = demo.get("/metrics", {"Accept": OM_ACCEPT})
    demo.finish()
    if not headers.get("Content-Type", "").startswith("application/openmetrics-text; version=1.0.0"):
        fail(f"Content-Type {headers.get('Content-Type')}")
    try:
        families = list(text_string_to_metric_families(body))
    except ValueError as e:
        fail(f"the OpenMetrics parser rejects the body: {e}")
    types = {f.name: f.type for f in families}
    for name, typ in [("vigil_component_execution_seconds", "histogram"),
                      ("vigil_component_wakeup_latency_seconds", "histogram"),
                      ("vigil_component_cycles", "counter"),
                      ("vigil_component_status", "gauge"),
                      ("vigil_build", "info"),
                      ("vigil_supervisor_drain_seconds", "summary")]:
        if types.get(name) != typ:
            fail(f"{name}: type {types.get(name)}, expected {typ}")
    hist = next(f for f in families if f.name == "vigil_component_execution_seconds")
    for s in hist.samples:
        if s.name.endswith("_bucket") and s.labels["le"] == "+Inf":
            count = next(c.value for c in hist.samples if c.name.endswith("_count")
                         and c.labels["component"] == s.labels["component"])
            if s.value != count:
                fail(f"+Inf {s.value} != count {count} for {s.labels['component']}")
    print(f"OpenMetrics parser: {len(families)} families accepted")


def documented_metrics(source):
    path = os.path.join(source, "docs", "reference", "metrics.md")
    names = set()
    with open(path, encoding="utf-8") as f:
        for line in f:
            m = re.match(r"\|\s*`(vigil_[a-z0-9_]+)`", line)
            if m:
                names.add(m.group(1))
    if not names:
        fail(f"no metric found in {path}")
    return names


def check_reference(args):
    documented = documented_metrics(args.source)
    demo = Demo(args.vigil, duration=20)
    demo.wait_healthy()
    time.sleep(3)  # a few cycles: every family has samples (CAN frames, silences, threads)
    _, _, body = demo.get("/metrics")
    demo.finish()
    exposed = exposed_families(body)
    # Read through netlink from a bus's SocketCAN interface (buses.<bus>.interface): the demo's
    # simulated bus has none.
    live_can_only = {"vigil_can_bus_controller_state", "vigil_can_bus_error_counter",
                     "vigil_can_bus_restarts_total", "vigil_can_bus_errors_total"}
    missing = sorted(documented - exposed - live_can_only)
    undocumented = sorted(exposed - documented)
    if missing:
        fail(f"documented in docs/reference/metrics.md but not exposed by the demo: {missing}")
    if undocumented:
        fail(f"exposed but not in docs/reference/metrics.md: {undocumented}")
    print(f"{len(exposed)} families, all documented; every documented one exposed")


class RowReader(html.parser.HTMLParser):
    """The dashboard's status rows and chart cards, from Chromium's dumped DOM."""

    def __init__(self):
        super().__init__()
        self.rows = {}
        self.cards = set()
        self.canvases = 0
        self.body = {}
        self.unit_heads = {}  # unit kind -> its table's column titles
        self.roots = []  # the root causes' tree: each root, in order
        self.dependents = {}  # root -> the reports it explains
        self._root = None
        self._kind = None
        self._in_th = False

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "li" and "data-root" in a:
            self._root = a["data-root"]
            self.roots.append(self._root)
        if tag == "li" and "data-dependent" in a and self._root is not None:
            self.dependents.setdefault(self._root, []).append(a["data-dependent"])
        if tag == "tr" and "data-component" in a:
            self.rows[a["data-component"]] = a.get("data-status")
        if tag == "div" and "card" in (a.get("class") or "").split():
            self.cards.add(a.get("data-component"))
        if tag == "canvas":
            self.canvases += 1
        if tag == "body":
            self.body = a
        if tag == "table" and "data-kind" in a:
            self._kind = a["data-kind"]
            self.unit_heads[self._kind] = []
        if tag == "th" and self._kind:
            self._in_th = True

    def handle_endtag(self, tag):
        if tag == "table":
            self._kind = None
        if tag == "th":
            self._in_th = False

    def handle_data(self, data):
        if self._in_th and self._kind:
            self.unit_heads[self._kind].append(data.strip())


def chromium_binary():
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        path = shutil.which(name)
        if path:
            return path
    return None


def run_chromium(binary, url, extra, profile):
    cmd = [binary, "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
           "--no-first-run", "--no-default-browser-check", f"--user-data-dir={profile}",
           "--virtual-time-budget=6000", "--window-size=1400,1600", *extra, url]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    if r.returncode != 0:
        fail(f"chromium exited with {r.returncode}: {r.stderr[-2000:]}")
    return r.stdout


def check_chromium(args):
    binary = chromium_binary()
    if not binary:
        skip("chromium not found (Debian package chromium)")
    demo = Demo(args.vigil, duration=60)
    demo.wait_healthy()
    time.sleep(5)  # past the encoder's failure at ~4 s: statuses of every level
    # Every status the API gives while the page runs (it polls the same reports for its 6 s):
    # a component that flips (a motor's WARN under load) may be shown in any of them.
    seen = {}
    stop = threading.Event()

    def watch_api():
        while not stop.is_set():
            try:
                _, _, body = demo.get("/api/v1/reports")
                for c in json.loads(body)["components"]:
                    seen.setdefault(c["name"], set()).add(c["status"])
            except (OSError, ValueError, KeyError):
                pass
            stop.wait(0.05)

    with tempfile.TemporaryDirectory() as profile:
        _, _, before = demo.get("/api/v1/reports")
        watcher = threading.Thread(target=watch_api)
        watcher.start()
        try:
            dom = run_chromium(binary, demo.base + "/", ["--dump-dom"], profile)
        finally:
            stop.set()
            watcher.join()
        _, _, after = demo.get("/api/v1/reports")
        shot = os.path.join(args.out, "dashboard.png")
        if os.path.exists(shot):
            os.remove(shot)
        run_chromium(binary, demo.base + "/", [f"--screenshot={shot}"], profile)
    demo.finish()
    reader = RowReader()
    reader.feed(dom)
    api_before = {c["name"]: c["status"] for c in json.loads(before)["components"]}
    api_after = {c["name"]: c["status"] for c in json.loads(after)["components"]}
    if reader.body.get("data-loaded") != "1":
        fail("the page never loaded the reports (body has no data-loaded=1):\n" + dom[:3000])
    problems = []
    for name, status in api_after.items():
        shown = reader.rows.get(name)
        if shown is None:
            problems.append(f"{name}: not in the table")
        elif shown not in {status, api_before.get(name)} | seen.get(name, set()):
            during = "/".join(sorted(seen.get(name, set())))
            problems.append(f"{name}: page says {shown}, API says {api_before.get(name)} before, "
                            f"{during} during, {status} after")
    if problems:
        fail("; ".join(problems))
    if "ERROR" not in reader.rows.values():
        fail("no component shows ERROR (the demo's encoder throws after ~4 s)")
    # Units (the demo's CAN nodes and groups) in a table of their kind, with their fields'
    # names as column titles.
    unit_kinds = {c["kind"] for c in json.loads(after)["components"] if "fields" in c}
    for kind in unit_kinds:
        heads = reader.unit_heads.get(kind)
        if heads is None:
            fail(f"no table for the {kind} units")
        if kind == "can_node" and not {"frames rx", "rx gap p50 / p99 / max"} <= set(heads):
            fail(f"the can_node table's columns are {heads}")
    # The diagnosis graph's tree: drive_5 (silent from 3 s) is a root cause, right_arm under it.
    if "can0/drive_5" in json.loads(after).get("root_causes", []):
        if "can0/drive_5" not in reader.roots:
            fail(f"the root causes shown are {reader.roots}, without can0/drive_5")
        if "can group right_arm" not in reader.dependents.get("can0/drive_5", []):
            fail(f"drive_5 explains {reader.dependents.get('can0/drive_5')}, not right_arm")
    components = {n for n, c in ((c["name"], c) for c in json.loads(after)["components"])
                  if c["kind"] == "component"}
    if reader.body.get("data-charts") == "1":
        if not components <= reader.cards:
            fail(f"chart cards missing for {sorted(components - reader.cards)}")
        if reader.canvases < 2 * len(components):
            fail(f"{reader.canvases} canvases for {len(components)} components")
        charts = f"{len(reader.cards)} chart cards"
    else:
        charts = "no charts (built without Chart.js)"
    if not os.path.exists(shot) or os.path.getsize(shot) < 10000:
        fail(f"no screenshot at {shot}")
    print(f"dashboard: {len(reader.rows)} rows match the JSON API, {charts}; screenshot {shot}")


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def check_prometheus(args):
    prometheus = shutil.which("prometheus")
    if not prometheus:
        skip("prometheus not found (Debian package prometheus)")
    demo = Demo(args.vigil, duration=60)
    with tempfile.TemporaryDirectory() as tmp:
        with open(os.path.join(tmp, "rules.yml"), "w") as f:
            f.write("""groups:
  - name: vigil
    rules:
      - alert: VigilComponentError
        expr: vigil_component_status >= 2
        labels: {severity: page}
        annotations: {summary: "{{ $labels.component }} on {{ $labels.robot }} is ERROR or STALE"}
""")
        with open(os.path.join(tmp, "prometheus.yml"), "w") as f:
            f.write(f"""global:
  scrape_interval: 1s
  evaluation_interval: 1s
  external_labels: {{robot: test-robot}}
rule_files: [rules.yml]
scrape_configs:
  - job_name: vigil
    static_configs: [{{targets: ['127.0.0.1:{demo.port}']}}]
""")
        web = free_port()
        log = open(os.path.join(args.out, "prometheus.log"), "w")
        prom = subprocess.Popen([prometheus, f"--config.file={tmp}/prometheus.yml",
                                 "--enable-feature=exemplar-storage",
                                 f"--web.listen-address=127.0.0.1:{web}",
                                 f"--storage.tsdb.path={tmp}/data"],
                                stdout=log, stderr=subprocess.STDOUT)

        def query(path, **params):
            url = f"http://127.0.0.1:{web}{path}?" + urllib.parse.urlencode(params)
            with urllib.request.urlopen(url, timeout=5) as r:
                doc = json.loads(r.read())
            if doc.get("status") != "success":
                raise RuntimeError(str(doc))
            return doc["data"]

        def poll(what, fn, timeout=40):
            end = time.time() + timeout
            last = None
            while time.time() < end:
                if prom.poll() is not None:
                    fail(f"prometheus exited with {prom.returncode} (see {log.name})")
                try:
                    result = fn()
                    if result:
                        return result
                    last = "empty"
                except (urllib.error.URLError, ConnectionError, OSError, RuntimeError) as e:
                    last = str(e)
                time.sleep(0.5)
            fail(f"{what}: nothing after {timeout} s ({last})")

        try:
            components = poll("vigil_component_status", lambda: {
                r["metric"]["component"] for r in
                query("/api/v1/query", query='vigil_component_status{kind="component"}')["result"]})
            expected = {"motor_left", "motor_right", "sensor_fusion", "planner", "load_ramp",
                        "logger", "encoder", "can_io"}
            if not expected <= components:
                fail(f"Prometheus knows {sorted(components)}, expected {sorted(expected)}")
            q = ('histogram_quantile(0.99, sum by (le) '
                 '(rate(vigil_component_execution_seconds_bucket{component="motor_left"}[5s])))')

            def quantile():
                res = query("/api/v1/query", query=q)["result"]
                if res and res[0]["value"][1] not in ("NaN", "+Inf"):
                    return float(res[0]["value"][1])
                return None
            p99 = poll("histogram_quantile", quantile)
            if not 0 < p99 < 0.01:
                fail(f"p99 of motor_left's execution time {p99} s is not plausible")

            def firing():
                alerts = query("/api/v1/alerts")["alerts"]
                return {a["labels"]["component"] for a in alerts
                        if a["state"] == "firing" and a["labels"]["alertname"] == "VigilComponentError"}
            fired = poll("alert VigilComponentError for encoder",
                         lambda: (lambda f: f if "encoder" in f else None)(firing()))
            healthy = {"motor_left", "motor_right", "sensor_fusion", "planner"}
            if fired & healthy:
                fail(f"the alert fires for healthy components: {sorted(fired & healthy)}")
            targets = query("/api/v1/targets")["activeTargets"]
            if not targets or targets[0]["health"] != "up":
                fail(f"target not up: {targets}")
            exemplars, traced = check_exemplars(demo, query, poll)
        finally:
            prom.send_signal(signal.SIGTERM)
            try:
                prom.wait(timeout=20)
            except subprocess.TimeoutExpired:
                prom.kill()
            log.close()
    demo.finish()
    print(f"Prometheus: {len(components)} components, p99(motor_left execution) = "
          f"{p99 * 1e6:.1f} us, alert firing for {sorted(fired)}; {exemplars} exemplars stored, "
          f"{traced}")


def check_exemplars(demo, query, poll):
    """The exemplars arrive in Prometheus' exemplar storage: on the timing histograms' buckets
    (each within its bucket, naming a cycle), and one names a flight record that the demo serves
    as a Perfetto trace."""
    def stored():
        now = time.time()
        found = []
        for family in ("vigil_component_execution_seconds_bucket",
                       "vigil_component_wakeup_latency_seconds_bucket",
                       "vigil_component_total_seconds_bucket",
                       "vigil_component_measured_period_seconds_bucket",
                       "vigil_component_overruns_total"):
            for series in query("/api/v1/query_exemplars", query=family,
                                start=now - 600, end=now + 60):
                for e in series["exemplars"]:
                    found.append((series["seriesLabels"], e))
        traced = [(s, e) for s, e in found if "trace" in e["labels"]]
        return (found, traced) if traced else None
    found, traced = poll("an exemplar naming a flight-recorder trace", stored, timeout=60)
    for series, e in found:
        if not re.fullmatch(r"[1-9][0-9]*", e["labels"].get("cycle", "")):
            fail(f"exemplar without a cycle: {series} {e}")
        le = series.get("le")
        if le is not None and float(e["value"]) > float(le):
            fail(f"exemplar above its bucket: {series} {e}")
        if abs(float(e["timestamp"]) - time.time()) > 600:
            fail(f"exemplar timestamp not the cycle's time: {series} {e}")
    series, e = traced[0]
    status, headers, body = demo.get(f"/api/v1/events/{e['labels']['trace']}/trace")
    events = json.loads(body)["traceEvents"]
    cycles = {str(ev.get("args", {}).get("cycle")) for ev in events}
    if e["labels"]["cycle"] not in cycles:
        fail(f"the trace of {series} {e} does not hold cycle {e['labels']['cycle']}")
    return len(found), (f"{series['component']} cycle {e['labels']['cycle']} -> trace "
                        f"{e['labels']['trace']} ({len(events)} trace events)")


def check_fleet(args):
    """docs/fleet/: the robot's agent remote-writes to a central Prometheus that evaluates the
    documented alert rules; the Grafana dashboard only uses documented metrics."""
    fleet = os.path.join(args.source, "docs", "fleet")
    documented = documented_metrics(args.source)
    with open(os.path.join(fleet, "grafana-vigil-fleet.json")) as f:
        dashboard = json.load(f)
    used = set()
    for panel in dashboard["panels"]:
        for t in panel.get("targets", []):
            for name in re.findall(r"\b(vigil_[a-z0-9_]+)", t["expr"]):
                used.add(re.sub(r"_(bucket|sum|count)$", "", name)
                         if re.sub(r"_(bucket|sum|count)$", "", name) in documented else name)
    if not used or used - documented:
        fail(f"the Grafana dashboard uses undocumented metrics: {sorted(used - documented)}")
    print(f"Grafana dashboard: {len(dashboard['panels'])} panels, metrics {sorted(used)}")

    prometheus = shutil.which("prometheus")
    if not prometheus:
        skip("prometheus not found (Debian package prometheus); the dashboard JSON was checked")
    promtool = shutil.which("promtool")
    if promtool:
        r = subprocess.run([promtool, "check", "rules", os.path.join(fleet, "vigil-alerts.yml")],
                           capture_output=True, text=True)
        if r.returncode != 0:
            fail("promtool check rules: " + r.stdout + r.stderr)
    demo = Demo(args.vigil, duration=90)
    with tempfile.TemporaryDirectory() as tmp:
        central_port, agent_port = free_port(), free_port()
        shutil.copy(os.path.join(fleet, "vigil-alerts.yml"), tmp)
        with open(os.path.join(fleet, "prometheus-central.yml")) as f:
            central = f.read().replace("evaluation_interval: 15s", "evaluation_interval: 1s")
        with open(os.path.join(tmp, "central.yml"), "w") as f:
            f.write(central)
        with open(os.path.join(fleet, "prometheus-agent.yml")) as f:
            agent = (f.read().replace("127.0.0.1:9479", f"127.0.0.1:{demo.port}")
                     .replace("central.example:9090", f"127.0.0.1:{central_port}")
                     .replace("scrape_interval: 5s", "scrape_interval: 1s")
                     .replace("queue_config: {", "queue_config: {batch_send_deadline: 1s, "))
        with open(os.path.join(tmp, "agent.yml"), "w") as f:
            f.write(agent)
        log = open(os.path.join(args.out, "prometheus-fleet.log"), "w")
        procs = [
            subprocess.Popen([prometheus, f"--config.file={tmp}/central.yml",
                              "--web.enable-remote-write-receiver",
                              "--enable-feature=exemplar-storage",
                              f"--web.listen-address=127.0.0.1:{central_port}",
                              f"--storage.tsdb.path={tmp}/central"], stdout=log,
                             stderr=subprocess.STDOUT),
            subprocess.Popen([prometheus, "--enable-feature=agent,exemplar-storage",
                              f"--config.file={tmp}/agent.yml",
                              f"--web.listen-address=127.0.0.1:{agent_port}",
                              f"--storage.agent.path={tmp}/agent"], stdout=log,
                             stderr=subprocess.STDOUT)]

        def query(path, **params):
            url = f"http://127.0.0.1:{central_port}{path}?" + urllib.parse.urlencode(params)
            with urllib.request.urlopen(url, timeout=5) as r:
                doc = json.loads(r.read())
            if doc.get("status") != "success":
                raise RuntimeError(str(doc))
            return doc["data"]

        def poll(what, fn, timeout=60):
            end = time.time() + timeout
            last = None
            while time.time() < end:
                for p in procs:
                    if p.poll() is not None:
                        fail(f"a prometheus exited with {p.returncode} (see {log.name})")
                try:
                    result = fn()
                    if result:
                        return result
                    last = "empty"
                except (urllib.error.URLError, ConnectionError, OSError, RuntimeError) as e:
                    last = str(e)
                time.sleep(0.5)
            fail(f"{what}: nothing after {timeout} s ({last})")

        try:
            robots = poll("vigil_component_status on the central Prometheus", lambda: {
                (r["metric"].get("robot"), r["metric"].get("site")) for r in query(
                    "/api/v1/query", query='vigil_component_status{component="motor_left"}')["result"]})
            if robots != {("robot-01", "lab")}:
                fail(f"robot identity on the central Prometheus: {robots}")

            def firing():
                return {(a["labels"]["robot"], a["labels"]["component"])
                        for a in query("/api/v1/alerts")["alerts"]
                        if a["state"] == "firing" and a["labels"]["alertname"] == "VigilComponentError"}
            fired = poll("VigilComponentError for robot-01/encoder",
                         lambda: (lambda f: f if ("robot-01", "encoder") in f else None)(firing()))
            # The exemplars travel with the samples (send_exemplars), robot label included.
            exemplars, traced = check_exemplars(demo, query, poll)
        finally:
            for p in procs:
                p.send_signal(signal.SIGTERM)
            for p in procs:
                try:
                    p.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    p.kill()
            log.close()
    demo.finish()
    print(f"fleet: agent -> remote write -> central; robot identity {sorted(robots)}; "
          f"alerts firing {sorted(fired)}; {exemplars} exemplars on the central Prometheus, "
          f"{traced}")


def raw_request(port, data, timeout=10):
    """Sends raw bytes, returns the status code of the answer (None when the server closed)."""
    with socket.create_connection(("127.0.0.1", port), timeout=timeout) as s:
        try:
            s.sendall(data)
        except (BrokenPipeError, ConnectionResetError):
            pass
        buf = b""
        try:
            while b"\r\n" not in buf:
                chunk = s.recv(4096)
                if not chunk:
                    break
                buf += chunk
        except ConnectionResetError:
            pass
    m = re.match(rb"HTTP/1\.[01] (\d{3})", buf)
    return int(m.group(1)) if m else None


def check_requests(args):
    # The default address: PORT alone listens on 127.0.0.1 only.
    demo = Demo(args.vigil, listen="0", duration=60, extra=["--json", os.path.join(args.out, "http_requests.json")])
    demo.wait_healthy()
    port = demo.port
    results = {}
    results["POST"] = raw_request(port, b"POST /metrics HTTP/1.1\r\nHost: 127.0.0.1\r\n"
                                        b"Content-Length: 5\r\n\r\nhello")
    results["DELETE"] = raw_request(port, b"DELETE / HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
    results["/nope"] = raw_request(port, b"GET /nope HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
    results["huge header"] = raw_request(
        port, b"GET /metrics HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Big: " + b"a" * 100000 + b"\r\n\r\n")
    results["garbage line"] = raw_request(port, b"\x16\x03\x01garbage \xff\xfe\r\n\r\n")
    results["no version"] = raw_request(port, b"GET\r\n\r\n")
    results["long URI"] = raw_request(port, b"GET /" + b"x" * 20000 + b" HTTP/1.1\r\n\r\n")
    results["foreign Host"] = raw_request(port, b"GET /metrics HTTP/1.1\r\nHost: evil.example\r\n\r\n")
    expect = {"POST": {405}, "DELETE": {405}, "/nope": {404}, "foreign Host": {403}}
    problems = []
    for what, status in results.items():
        allowed = expect.get(what, set(range(400, 500)))
        if status not in allowed:
            problems.append(f"{what}: {status}, expected {sorted(allowed)[:3]}...")
    print("bad requests:", results)

    # Slow clients: as many idle connections as worker threads hold them only until the read
    # timeout (2 s); a scrape meanwhile is served within that bound.
    idle = [socket.create_connection(("127.0.0.1", port)) for _ in range(4)]
    t0 = time.time()
    status, _, _ = demo.get("/metrics", timeout=15)
    slow_wait = time.time() - t0
    for s in idle:
        s.close()
    if status != 200 or slow_wait > 8:
        problems.append(f"with 4 idle connections a scrape took {slow_wait:.1f} s ({status})")

    # 100 concurrent scrapers.
    def scrape(_):
        try:
            return demo.get("/metrics", timeout=30)[0]
        except Exception as e:  # noqa: BLE001 - reported below
            return repr(e)
    t0 = time.time()
    with concurrent.futures.ThreadPoolExecutor(100) as pool:
        statuses = list(pool.map(scrape, range(100)))
    burst = time.time() - t0
    if statuses.count(200) != 100:
        problems.append(f"100 scrapers: {statuses.count(200)} served; others {set(statuses) - {200}}")
    print(f"100 concurrent scrapers: {statuses.count(200)} x 200 in {burst:.2f} s; "
          f"scrape with 4 idle connections: {slow_wait:.2f} s")

    # A second server on the same port is refused, clearly.
    second = subprocess.run([args.vigil, "demo", "--duration", "5", "--no-live", "--http",
                             str(port)], capture_output=True, text=True, timeout=60)
    if second.returncode == 0 or "taken" not in second.stderr:
        problems.append(f"second demo on port {port}: exit {second.returncode}, "
                        f"stderr {second.stderr.strip()!r}")
    else:
        print("second server:", second.stderr.strip())

    # The listener: 127.0.0.1 only.
    ss = shutil.which("ss")
    if ss:
        out = subprocess.run([ss, "-ltnH"], capture_output=True, text=True).stdout
        listeners = [line.split()[3] for line in out.splitlines()
                     if line.split()[3].endswith(f":{port}")]
        print("ss -ltn:", listeners)
        if listeners != [f"127.0.0.1:{port}"]:
            problems.append(f"listeners on port {port}: {listeners}, expected 127.0.0.1 only")
    else:
        print("ss not found (iproute2): listener address not checked")

    # Still alive and serving, and exits cleanly.
    status, _, body = demo.get("/healthz")
    if status != 200:
        problems.append(f"/healthz after the abuse: {status} {body}")
    demo.finish()
    if problems:
        fail("; ".join(problems))


# What only the HTTP server needs: the module and the libraries Debian's cpp-httplib brings.
HTTP_ONLY = ("libvigil_http", "libcpp-httplib", "libcrypto", "libssl")


def mapped_files(pid):
    """The files mapped into process `pid`."""
    with open(f"/proc/{pid}/maps") as f:
        return {line.split()[5] for line in f if len(line.split()) >= 6}


def check_module(args):
    problems = []
    # Without --http: none of it is mapped (memory locked, it would all be resident).
    proc = subprocess.Popen([args.vigil, "demo", "--duration", "4", "--no-live"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    time.sleep(2)
    files = mapped_files(proc.pid) if proc.poll() is None else None
    out, _ = proc.communicate(timeout=30)
    if files is None or proc.returncode != 0:
        fail(f"the demo without --http exited with {proc.returncode}:\n{out}")
    leaked = sorted(f for f in files if any(n in f for n in HTTP_ONLY))
    if leaked:
        problems.append(f"without --http the demo maps {leaked}")
    not_module = next((f for f in files if "libfmt" in f), None)

    # With --http: the module is opened, and serves.
    demo = Demo(args.vigil, duration=20)
    demo.wait_healthy()
    files = mapped_files(demo.proc.pid)
    if not any("libvigil_http.so" in f for f in files):
        problems.append("with --http the demo serves but libvigil_http.so is not mapped")
    demo.finish()

    # VIGIL_HTTP_MODULE names the only file tried; a bad one is an error that names it.
    cases = [("/nonexistent/libvigil_http.so", "No such file")]
    if not_module:
        cases.append((not_module, "not a vigil HTTP module"))
    for path, why in cases:
        env = dict(os.environ, VIGIL_HTTP_MODULE=path)
        r = subprocess.run([args.vigil, "demo", "--duration", "3", "--no-live", "--http",
                            "127.0.0.1:0"], env=env, capture_output=True, text=True, timeout=60)
        said = r.stdout + r.stderr
        if r.returncode == 0 or path not in said or why not in said or \
                "VIGIL_HTTP_MODULE" not in said:
            problems.append(f"VIGIL_HTTP_MODULE={path}: exit {r.returncode}, expected an error "
                            f"naming the file and '{why}':\n{said}")
    if problems:
        fail("; ".join(problems))
    print(f"OK: without --http none of {HTTP_ONLY} is mapped; with it the module is; "
          f"{len(cases)} bad VIGIL_HTTP_MODULE refused by name")


CHECKS = {"promtool": check_promtool, "openmetrics": check_openmetrics,
          "reference": check_reference, "chromium": check_chromium,
          "prometheus": check_prometheus, "requests": check_requests, "fleet": check_fleet,
          "module": check_module}


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("check", choices=sorted(CHECKS))
    p.add_argument("--vigil", required=True)
    p.add_argument("--source", required=True)
    p.add_argument("--out", required=True)
    args = p.parse_args()
    os.makedirs(args.out, exist_ok=True)
    CHECKS[args.check](args)


if __name__ == "__main__":
    main()
