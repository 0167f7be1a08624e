#!/usr/bin/python3
"""An independent reader of J1939 DM1, DM2 and address claims, to check `vigil can-stats`.

python3-can (Debian `python3-can`) reads the candump log; this script reassembles the
transport protocol (J1939-21 BAM and RTS/CTS, well-formed sessions only), decodes every DM1
and DM2 (J1939-73: the same layout) and address claim (J1939-81) itself, and compares with
what `vigil can-stats --node-map j1939 --json LOG` reports: the frame count, each source
address's active DTCs, lamps, previously active DTCs (its latest DM2) and claimed NAME, and the
sequence of dtc_active / dtc_cleared events.

usage: j1939_reference.py VIGIL LOG...   (exit 0: equal, 1: different, 77: python3-can absent)
"""
import json
import subprocess
import sys

try:
    import can  # python3-can
except ImportError:
    print("skipped: python3-can absent")
    sys.exit(77)

LAMPS = ["off", "on", "error", "n/a"]


def frames(path):
    """(timestamp, id, data) of every frame, as python-can reads the log."""
    out = []
    for m in can.CanutilsLogReader(path):
        if m.is_error_frame or m.is_remote_frame:
            continue
        out.append((m.timestamp, m.arbitration_id, bytes(m.data), m.is_extended_id))
    return out


def decode_dm1(p, single):
    if len(p) < 6 or (not single and (len(p) - 2) % 4 != 0):
        return None
    lamps = {
        "mil": LAMPS[(p[0] >> 6) & 3],
        "red_stop": LAMPS[(p[0] >> 4) & 3],
        "amber_warning": LAMPS[(p[0] >> 2) & 3],
        "protect": LAMPS[p[0] & 3],
    }
    dtcs = []
    records = [p[2:6]] if single else [p[i:i + 4] for i in range(2, len(p), 4)]
    for r in records:
        if r in (b"\x00\x00\x00\x00", b"\xff\xff\xff\xff"):
            continue
        spn = r[0] + (r[1] << 8) + ((r[2] >> 5) << 16)
        d = (spn, r[2] & 0x1F, r[3] & 0x7F, r[3] >> 7)
        if all((x[0], x[1]) != (d[0], d[1]) for x in dtcs):
            dtcs.append(d)
    return lamps, dtcs


def reference(paths):
    count = 0
    active = {}  # sa -> list of dtc tuples
    previous = {}  # sa -> list of dtc tuples, from its latest DM2
    lamps = {}
    names = {}
    events = []
    bam = {}  # sa -> [pgn, size, packets, data, time of the latest frame]
    cm = {}  # (sa, da) -> [pgn, size, packets, data, time of the latest frame]

    def dm1(sa, payload, single):
        got = decode_dm1(payload, single)
        if got is None:
            return
        lamps[sa], dtcs = got
        old = active.get(sa, [])
        for o in old:
            if all((o[0], o[1]) != (d[0], d[1]) for d in dtcs):
                events.append(("dtc_cleared", sa, o[0], o[1]))
        for d in dtcs:
            if all((o[0], o[1]) != (d[0], d[1]) for o in old):
                events.append(("dtc_active", sa, d[0], d[1]))
        active[sa] = dtcs

    def dm2(sa, payload, single):
        got = decode_dm1(payload, single)  # DM2 has DM1's layout
        if got is not None:
            previous[sa] = got[1]

    for path in paths:
        for t, ident, data, extended in frames(path):
            count += 1
            if not extended:
                continue
            sa = ident & 0xFF
            pf = (ident >> 16) & 0xFF
            ps = (ident >> 8) & 0xFF
            pgn = ((ident >> 8) & 0x3FF00) if pf < 240 else ((ident >> 8) & 0x3FFFF)
            if pgn == 0xFECA:
                dm1(sa, data, True)
            elif pgn == 0xFECB:
                dm2(sa, data, True)
            elif pgn == 0xEE00 and len(data) == 8:
                names[sa] = int.from_bytes(data, "little")
            elif pgn == 0xEC00 and len(data) == 8:
                size = data[1] | data[2] << 8
                tp_pgn = data[5] | data[6] << 8 | data[7] << 16
                if data[0] == 32:
                    bam[sa] = [tp_pgn, size, data[3], b"", t]
                elif data[0] == 16:
                    cm[(sa, ps)] = [tp_pgn, size, data[3], b"", t]
                elif data[0] == 17 and (ps, sa) in cm:
                    cm[(ps, sa)][4] = t
            elif pgn == 0xEB00 and len(data) == 8:
                s = bam.get(sa) if ps == 0xFF else cm.get((sa, ps))
                # J1939-21 T1 (750 ms) between packets, T2 (1250 ms) after a CTS.
                if s is None or t - s[4] > (0.75 if ps == 0xFF else 1.25):
                    continue
                if data[0] != len(s[3]) // 7 + 1:
                    continue
                s[3] += data[1:]
                s[4] = t
                if data[0] == s[2]:
                    if s[0] == 0xFECA:
                        dm1(sa, s[3][:s[1]], False)
                    elif s[0] == 0xFECB:
                        dm2(sa, s[3][:s[1]], False)
                    if ps == 0xFF:
                        del bam[sa]
                    else:
                        del cm[(sa, ps)]
    return count, active, previous, lamps, names, events


def main():
    vigil, logs = sys.argv[1], sys.argv[2:]
    for log in logs:
        try:
            open(log, "rb").close()
        except OSError:
            print(f"skipped: {log} absent")
            return 77
    count, active, previous, lamps, names, events = reference(logs)
    out = subprocess.run([vigil, "can-stats", "--node-map", "j1939", "--json", *logs],
                         check=True, capture_output=True, text=True).stdout
    report = json.loads(out)
    problems = []
    if report["frames"] != count:
        problems.append(f"frames: vigil {report['frames']}, python-can {count}")
    nodes = {n["node"]: n for n in report["j1939"]}
    for sa in sorted(set(active) | set(previous) | set(names)):
        n = nodes.get(sa)
        if n is None:
            problems.append(f"0x{sa:02X}: missing in vigil's j1939 array")
            continue
        mine = [(d["spn"], d["fmi"], d["occurrences"], int(d["conversion_method"]))
                for d in n["active_dtcs"]]
        if mine != active.get(sa, []):
            problems.append(f"0x{sa:02X} DTCs: vigil {mine}, reference {active.get(sa, [])}")
        mine = [(d["spn"], d["fmi"], d["occurrences"], int(d["conversion_method"]))
                for d in n["previously_active_dtcs"]]
        if mine != previous.get(sa, []):
            problems.append(f"0x{sa:02X} DM2 DTCs: vigil {mine}, "
                            f"reference {previous.get(sa, [])}")
        if sa in lamps and {k: n["lamps"][k] for k in lamps[sa]} != lamps[sa]:
            problems.append(f"0x{sa:02X} lamps: vigil {n['lamps']}, reference {lamps[sa]}")
        if sa in names and int(n["claimed_name"]["raw"], 16) != names[sa]:
            problems.append(f"0x{sa:02X} NAME: vigil {n['claimed_name']['raw']}, "
                            f"reference 0x{names[sa]:016X}")
    mine = []
    for e in report["protocol"]["recent_events"]:
        if e["kind"] in ("dtc_active", "dtc_cleared"):
            spn, fmi = e["detail"].split(" ")[1], e["detail"].split(" ")[3]
            mine.append((e["kind"], e["node"], int(spn), int(fmi)))
    if mine != events:
        problems.append(f"events: vigil {mine}, reference {events}")
    for p in problems:
        print(p)
    print(f"{count} frames, {len(active)} nodes with DM1, {len(previous)} with DM2, "
          f"{len(names)} address claims, "
          f"{len(events)} DTC events: {'equal' if not problems else 'DIFFERENT'}")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
