// vigil's live dashboard: polls the JSON API (docs/reference/http.md) and draws a status table
// and, when Chart.js is served at /static/chart.js, per-component charts: execution-time and
// wake-up latency histograms, and a recent history of p99s and overruns.
// Plain browser JavaScript, no build step; every text from the server goes through textContent.
(function () {
  'use strict';
  const body = document.body;
  const refreshMs = Math.min(1000, Math.max(200, Number(body.dataset.refreshMs) || 500));
  const chartsWanted = body.dataset.charts === '1';

  let chartsReady = false;
  let lastCycle = -1;
  let boundsLabels = null;
  const rows = new Map();   // name -> <tr>
  const unitTables = new Map();  // unit kind -> {table, head, tbody}
  const cards = new Map();  // name -> {card, badge, hist, line}

  document.getElementById('version').textContent = body.dataset.version || '';

  function fmtNs(ns) {
    if (ns === null || ns === undefined || !isFinite(ns)) return '-';
    const a = Math.abs(ns);
    if (a < 1e3) return ns.toFixed(0) + ' ns';
    if (a < 1e6) return (ns / 1e3).toPrecision(3) + ' µs';
    if (a < 1e9) return (ns / 1e6).toPrecision(3) + ' ms';
    return (ns / 1e9).toPrecision(3) + ' s';
  }
  function fmtBound(s) {
    return s < 1e-3 ? (s * 1e6) + 'µs' : s < 1 ? (s * 1e3) + 'ms' : s + 's';
  }
  function cell(tr, i, text, cls) {
    let td = tr.children[i];
    if (!td) {
      td = document.createElement('td');
      if (cls) td.className = cls;
      tr.appendChild(td);
    }
    if (td.textContent !== text) td.textContent = text;
    return td;
  }

  // A unit's field in a cell: durations (keys ending in _ns) in time units, a distribution as
  // p50 / p99 / max, counts and words as they are.
  function fieldText(key, v) {
    const ns = key.endsWith('_ns');
    if (v !== null && typeof v === 'object') {
      return v.count ? fmtNs(v.p50) + ' / ' + fmtNs(v.p99) + ' / ' + fmtNs(v.max) : '-';
    }
    if (typeof v === 'number') return ns ? fmtNs(v) : String(v);
    return v === null || v === undefined ? '-' : String(v);
  }
  // A field's column title: "rx_gap_ns" with a distribution -> "rx gap p50 / p99 / max".
  function fieldTitle(key, v) {
    const name = key.replace(/_ns$/, '').replace(/_/g, ' ');
    return v !== null && typeof v === 'object' ? name + ' p50 / p99 / max' : name;
  }

  // The table of one kind of unit (CAN nodes, CAN groups...), made on first sight, below the
  // components' table: name, status, state, a column per field, the messages.
  function unitTable(kind) {
    let t = unitTables.get(kind);
    if (t) return t;
    const table = document.createElement('table');
    table.className = 'units';
    table.dataset.kind = kind;
    const head = document.createElement('tr');
    table.appendChild(document.createElement('thead')).appendChild(head);
    const tbody = table.appendChild(document.createElement('tbody'));
    document.getElementById('units').appendChild(table);
    t = {table, head, tbody, keys: []};
    unitTables.set(kind, t);
    return t;
  }
  function setHead(t, kind, fieldsSeen) {
    const titles = [kind, 'status', 'state'];
    for (const [key, v] of fieldsSeen) titles.push(fieldTitle(key, v));
    titles.push('message');
    titles.forEach((title, i) => {
      const th = cell(t.head, i, title);
      if (th.tagName !== 'TD') return;
      const h = document.createElement('th');  // the first render made a td: make it a header
      h.textContent = title;
      t.head.replaceChild(h, th);
    });
  }

  function badgeCell(tr, i, status) {
    const st = cell(tr, i, '');
    let badge = st.firstChild;
    if (!badge) {
      badge = document.createElement('span');
      badge.className = 'badge';
      st.appendChild(badge);
    }
    badge.dataset.status = status;
    badge.textContent = status;
  }
  function rowOf(name, tbody) {
    let tr = rows.get(name);
    if (!tr) {
      tr = document.createElement('tr');
      tr.dataset.component = name;
      rows.set(name, tr);
    }
    tbody.appendChild(tr);  // keeps the server's order
    return tr;
  }

  // A report's messages, after the root causes that explain it (the diagnosis graph).
  function messageOf(r) {
    const own = r.messages.join('; ');
    if (!r.caused_by || r.caused_by.length === 0) return own;
    return 'caused by ' + r.caused_by.join(', ') + (own ? ': ' + own : '');
  }

  // The root causes as a tree: each root with its status and messages, the reports it explains
  // below it. Rebuilt each refresh (a few nodes); text only, never markup from the server.
  function renderCauses(doc) {
    const list = document.getElementById('causes');
    const roots = doc.root_causes || [];
    list.hidden = roots.length === 0;
    list.replaceChildren();
    const byName = new Map(doc.components.map((c) => [c.name, c]));
    for (const name of roots) {
      const r = byName.get(name);
      if (!r) continue;
      const li = document.createElement('li');
      li.dataset.root = name;
      const badge = document.createElement('span');
      badge.className = 'badge';
      badge.dataset.status = r.status;
      badge.textContent = r.status;
      li.appendChild(badge);
      const title = document.createElement('strong');
      title.textContent = ' ' + name;
      li.appendChild(title);
      li.appendChild(document.createTextNode(r.messages.length ? ': ' + r.messages.join('; ') : ''));
      const deps = doc.components.filter((c) => (c.caused_by || []).includes(name));
      if (deps.length) {
        const ul = document.createElement('ul');
        for (const d of deps) {
          const dl = document.createElement('li');
          dl.dataset.dependent = d.name;
          dl.textContent = d.name + ' (' + d.status + ')';
          ul.appendChild(dl);
        }
        li.appendChild(ul);
      }
      list.appendChild(li);
    }
  }

  function renderTable(doc) {
    renderCauses(doc);
    const tbody = document.querySelector('#status tbody');
    const seen = new Set();
    const units = new Map();  // kind -> reports, in the server's order
    for (const c of doc.components) {
      seen.add(c.name);
      if (c.fields) {  // a unit: shown in its kind's table
        if (!units.has(c.kind)) units.set(c.kind, []);
        units.get(c.kind).push(c);
        continue;
      }
      const tr = rowOf(c.name, tbody);
      tr.dataset.status = c.status;
      tr.dataset.kind = c.kind;
      cell(tr, 0, c.name);
      cell(tr, 1, c.kind);
      badgeCell(tr, 2, c.status);
      cell(tr, 3, c.state);
      cell(tr, 4, String(c.counters.cycles), 'num');
      const isComp = c.kind === 'component';
      // The max beside the p99, as in the text summary: one long cycle shows.
      const p99Max = (d) => (isComp && d.count ? fmtNs(d.p99) + ' / ' + fmtNs(d.max) : '-');
      cell(tr, 5, p99Max(c.timing.execution_ns), 'num');
      cell(tr, 6, p99Max(c.timing.latency_ns), 'num');
      cell(tr, 7, isComp ? c.window.overruns + ' / ' + c.counters.overruns : '-', 'num');
      cell(tr, 8, isComp ? String(c.counters.rt_losses) : '-', 'num');
      cell(tr, 9, messageOf(c), 'msg');
    }
    for (const [kind, list] of units) {
      const t = unitTable(kind);
      const fieldsSeen = new Map();  // key -> a value (for its title), in order of first sight
      for (const u of list) {
        for (const [key, v] of Object.entries(u.fields)) if (!fieldsSeen.has(key)) fieldsSeen.set(key, v);
      }
      setHead(t, kind, fieldsSeen);
      for (const u of list) {
        const tr = rowOf(u.name, t.tbody);
        tr.dataset.status = u.status;
        tr.dataset.kind = u.kind;
        cell(tr, 0, u.name);
        badgeCell(tr, 1, u.status);
        cell(tr, 2, u.state);
        let i = 3;
        for (const key of fieldsSeen.keys()) cell(tr, i++, fieldText(key, u.fields[key]), 'num');
        cell(tr, i, messageOf(u), 'msg');
      }
    }
    for (const [name, tr] of rows) {
      if (!seen.has(name)) {
        tr.remove();
        rows.delete(name);
      }
    }
    const overall = document.getElementById('overall');
    overall.dataset.status = doc.status;
    overall.textContent = doc.status;
    document.getElementById('meta').textContent =
        'monitor cycle ' + doc.cycle + ' · ' + doc.components.length + ' reports · refresh ' +
        (1000 / refreshMs).toFixed(0) + ' Hz';
  }

  // --- charts ---

  function makeCard(name) {
    const card = document.createElement('div');
    card.className = 'card';
    card.dataset.component = name;
    const h = document.createElement('h3');
    const badge = document.createElement('span');
    badge.className = 'badge';
    const title = document.createElement('span');
    title.textContent = name;
    h.append(badge, title);
    const plots = document.createElement('div');
    plots.className = 'plots';
    const mk = () => {
      const d = document.createElement('div');
      d.className = 'plot';
      const cv = document.createElement('canvas');
      d.appendChild(cv);
      plots.appendChild(d);
      return cv;
    };
    const histCanvas = mk();
    const lineCanvas = mk();
    card.append(h, plots);
    document.getElementById('charts').appendChild(card);
    const common = { animation: false, responsive: true, maintainAspectRatio: false,
                     plugins: { legend: { labels: { boxWidth: 10, font: { size: 10 } } } } };
    const hist = new Chart(histCanvas, {
      type: 'bar',
      data: { labels: [], datasets: [
        { label: 'execution %', data: [], backgroundColor: '#3b7dd8' },
        { label: 'latency %', data: [], backgroundColor: '#e07b39' }] },
      options: Object.assign({}, common, {
        scales: { x: { ticks: { font: { size: 9 }, maxRotation: 60 } },
                  y: { beginAtZero: true, ticks: { font: { size: 9 } },
                       title: { display: true, text: '% of cycles', font: { size: 9 } } } } })
    });
    const line = new Chart(lineCanvas, {
      type: 'line',
      data: { labels: [], datasets: [
        { label: 'exec p99 µs', data: [], borderColor: '#3b7dd8', pointRadius: 0, yAxisID: 'y' },
        { label: 'latency p99 µs', data: [], borderColor: '#e07b39', pointRadius: 0, yAxisID: 'y' },
        { label: 'overruns (window)', data: [], borderColor: '#d23b3b', pointRadius: 0,
          stepped: true, yAxisID: 'y1' }] },
      options: Object.assign({}, common, {
        scales: { x: { ticks: { font: { size: 9 }, maxTicksLimit: 6 },
                       title: { display: true, text: 's', font: { size: 9 } } },
                  y: { beginAtZero: true, ticks: { font: { size: 9 } } },
                  y1: { beginAtZero: true, position: 'right', grid: { drawOnChartArea: false },
                        ticks: { font: { size: 9 }, precision: 0 } } } })
    });
    const entry = { card, badge, hist, line };
    cards.set(name, entry);
    return entry;
  }

  function share(b) {
    const n = b.count || 0;
    return b.buckets.map(v => (n ? (100 * v) / n : 0));
  }

  function renderCharts(reports, hists, history) {
    if (!boundsLabels) {
      boundsLabels = hists.bounds_s.map(s => '≤' + fmtBound(s));
      boundsLabels.push('>' + fmtBound(hists.bounds_s[hists.bounds_s.length - 1]));
    }
    const status = new Map(reports.components.map(c => [c.name, c.status]));
    const seen = new Set();
    for (const h of hists.components) {
      if (!status.has(h.name)) continue;
      seen.add(h.name);
      const e = cards.get(h.name) || makeCard(h.name);
      e.badge.dataset.status = status.get(h.name);
      e.badge.textContent = status.get(h.name);
      // Show the buckets from the first to the last non-empty one of either histogram.
      const ex = share(h.execution), la = share(h.latency);
      let lo = ex.length, hi = -1;
      ex.forEach((v, i) => { if (v > 0 || la[i] > 0) { lo = Math.min(lo, i); hi = Math.max(hi, i); } });
      if (hi < lo) { lo = 0; hi = 0; }
      lo = Math.max(0, lo - 1);
      hi = Math.min(ex.length - 1, hi + 1);
      e.hist.data.labels = boundsLabels.slice(lo, hi + 1);
      e.hist.data.datasets[0].data = ex.slice(lo, hi + 1);
      e.hist.data.datasets[1].data = la.slice(lo, hi + 1);
      e.hist.update('none');
      const s = history.components[h.name];
      if (s) {
        e.line.data.labels = history.time_s.map(t => t.toFixed(0));
        e.line.data.datasets[0].data = s.execution_p99_s.map(v => (v === null ? null : v * 1e6));
        e.line.data.datasets[1].data = s.latency_p99_s.map(v => (v === null ? null : v * 1e6));
        e.line.data.datasets[2].data = s.window_overruns;
        e.line.update('none');
      }
    }
    for (const [name, e] of cards) {
      if (!seen.has(name)) {
        e.hist.destroy();
        e.line.destroy();
        e.card.remove();
        cards.delete(name);
      }
    }
  }

  async function getJson(url) {
    const r = await fetch(url, { cache: 'no-store' });
    if (!r.ok) throw new Error(url + ': ' + r.status);
    return r.json();
  }

  async function tick() {
    try {
      const reports = await getJson('/api/v1/reports');
      renderTable(reports);
      document.getElementById('conn').hidden = true;
      if (chartsReady && reports.cycle !== lastCycle) {
        const [hists, history] = await Promise.all([getJson('/api/v1/histograms'),
                                                    getJson('/api/v1/history')]);
        renderCharts(reports, hists, history);
      }
      lastCycle = reports.cycle;
      body.dataset.loaded = '1';
    } catch (e) {
      document.getElementById('conn').hidden = false;
    } finally {
      setTimeout(tick, refreshMs);
    }
  }

  if (chartsWanted) {
    const s = document.createElement('script');
    s.src = '/static/chart.js';
    s.onload = () => { chartsReady = typeof Chart !== 'undefined'; lastCycle = -1; };
    s.onerror = () => { document.getElementById('nocharts').hidden = false; };
    document.head.appendChild(s);
  } else {
    document.getElementById('nocharts').hidden = false;
  }
  tick();
})();
