#!/usr/bin/env python3
"""Watch the mrtwin twin's Foxglove live view with a plain Foxglove WebSocket client.

What the Foxglove app does, in ~100 lines: connect with the `foxglove.sdk.v1` subprotocol,
read the server's `advertise`, subscribe to every channel, and decode each binary
MessageData frame (opcode 1, subscription id u32, log time u64, payload): `cdr` channels
with the `ros2msg` schema the server advertised (mcap_ros2's dynamic decoder, as
Foxglove's), `json` channels as JSON. Prints a line a second, checks that every
`twin/fv_loop` point agrees with the sample and the twin output of its stamp, and exits 0
once --count loop points, a finite yield estimate and a diagnostics array have arrived (1 when
--timeout passes first).
"""
import argparse
import json
import math
import struct
import sys
import time
from collections import Counter

from mcap_ros2._dynamic import generate_dynamic
from websockets.sync.client import connect

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--url", default="ws://127.0.0.1:8765", help="the live view (default: ws://127.0.0.1:8765)")
parser.add_argument("--count", type=int, default=2000, help="stop after this many F-v loop points")
parser.add_argument("--timeout", type=float, default=30.0, help="give up after this many seconds")
parser.add_argument("--json", action="store_true", help="end with a one-line JSON summary")
args = parser.parse_args()

LEVELS = ["OK", "WARN", "ERROR", "STALE"]
KEYS = ["sensor/sample", "twin/output", "twin/predicted_force", "twin/yield_estimate", "twin/fv_loop", "diagnostics"]
deadline = time.monotonic() + args.timeout
channels, subscriptions = {}, {}  # channel id -> channel; subscription id -> (channel, decode)
counts, by_stamp = Counter(), {}
server, mismatches, loop = None, [], []
estimate, diagnostics = None, None


def decoder(ch):
    if ch["encoding"] == "json":
        return lambda data: json.loads(data)
    if ch["encoding"] == "cdr" and ch.get("schemaEncoding") == "ros2msg":
        return generate_dynamic(ch["schemaName"], ch["schema"])[ch["schemaName"]]
    raise SystemExit(f"channel {ch['topic']}: cannot decode encoding {ch['encoding']}")


def on_message(topic, msg, log_time):
    global estimate, diagnostics
    key = next((k for k in KEYS if topic.endswith(k)), topic)  # the topic without its namespace
    counts[key] += 1
    if key in ("sensor/sample", "twin/output"):
        stamp = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
        by_stamp.setdefault(stamp, {})[key] = msg
    elif key == "twin/fv_loop":
        stamp = round(msg["time_s"] * 1e9)
        seen = min(by_stamp, key=lambda s: abs(s - stamp)) if by_stamp else None
        pair = by_stamp.get(seen, {}) if seen is not None and abs(seen - stamp) < 1000 else {}
        if "sensor/sample" in pair and "twin/output" in pair:
            s, o = pair["sensor/sample"], pair["twin/output"]
            if (s.velocity, s.displacement, o.measured_force, o.predicted_force) != (
                    msg["velocity_m_s"], msg["displacement_m"], msg["measured_force_n"], msg["predicted_force_n"]):
                mismatches.append(stamp)
            counts["fv_loop_checked"] += 1
        loop.append((msg["velocity_m_s"], msg["measured_force_n"], msg["predicted_force_n"]))
        if len(by_stamp) > 5000:  # keep the recent stamps only
            for s in sorted(by_stamp)[:2500]:
                del by_stamp[s]
    elif key == "twin/yield_estimate":
        if math.isfinite(msg.tau0):  # NaN until the current at hand is identified
            estimate = msg
    elif key == "diagnostics":
        diagnostics = {s.name: s.level for s in msg.status}


def watch(ws):
    """Read frames until everything asked for arrived or the deadline passed."""
    global server
    last_print = time.monotonic()
    while time.monotonic() < deadline:
        if len(loop) >= args.count and estimate is not None and diagnostics is not None:
            break
        try:
            frame = ws.recv(timeout=max(0.01, deadline - time.monotonic()))
        except TimeoutError:
            break
        if isinstance(frame, str):
            op = json.loads(frame)
            if op["op"] == "serverInfo":
                server = op
            elif op["op"] == "advertise":
                subs = []
                for ch in op["channels"]:
                    channels[ch["id"]] = ch
                    sid = len(subscriptions) + 1
                    subscriptions[sid] = (ch, decoder(ch))
                    subs.append({"id": sid, "channelId": ch["id"]})
                ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
            continue
        if frame[0] != 1:  # MessageData only
            continue
        sid, log_time = struct.unpack_from("<IQ", frame, 1)
        ch, decode = subscriptions[sid]
        on_message(ch["topic"], decode(bytes(frame[13:])), log_time)
        if time.monotonic() - last_print > 1.0 and loop:
            last_print = time.monotonic()
            v, f, p = loop[-1]
            print(f"{len(loop)} loop points: v {v:+.4f} m/s, F measured {f:9.1f} N, predicted {p:9.1f} N", flush=True)


with connect(args.url, subprotocols=["foxglove.sdk.v1"], open_timeout=args.timeout) as ws:
    watch(ws)

if estimate is not None:
    print(f"yield estimate: tau0 {estimate.tau0 / 1e3:.1f} ± {estimate.tau0_std / 1e3:.1f} kPa at {estimate.current:.2f} A")
if diagnostics:
    print("diagnostics: " + ", ".join(f"{k} {LEVELS[v]}" for k, v in diagnostics.items()))
ok = len(loop) >= args.count and estimate is not None and diagnostics is not None and not mismatches
if args.json:
    vs = [v for v, _, _ in loop]
    dissipating = sum(1 for v, f, _ in loop if v * f > 0)
    print(json.dumps({
        "server": server and server.get("name"),
        "channels": sorted(ch["topic"] for ch in channels.values()),
        "counts": dict(counts),
        "loop_points": len(loop),
        "velocity_range": [min(vs), max(vs)] if vs else None,
        "dissipating_fraction": dissipating / len(loop) if loop else None,
        "rms_residual": (sum((f - p) ** 2 for _, f, p in loop) / len(loop)) ** 0.5 if loop else None,
        "rms_force": (sum(f * f for _, f, _ in loop) / len(loop)) ** 0.5 if loop else None,
        "mismatches": len(mismatches),
        "tau0": estimate and estimate.tau0,
        "diagnostics": diagnostics,
        "ok": ok,
    }))
sys.exit(0 if ok else 1)
