#!/usr/bin/env python3
"""Read an mrtwin bag (rosbag2, MCAP storage) with the python `rosbags` library.

Works on what `mrtwin record`, `mrtwin simulate --out DIR` and `mrtwin replay --out DIR`
write. The bag carries the message definitions as MCAP schemas, so rosbags' AnyReader
registers the mrtwin_msgs types from the bag itself; for a bag without them, --msgs adds
the repository's .msg files. Prints each topic with its message count and the first few
values of the mrtwin topics.
"""
import argparse
import json
import math
from collections import Counter
from pathlib import Path

from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("bag", type=Path, help="bag directory (or a single .mcap file)")
parser.add_argument("--show", type=int, default=3, help="values to print per topic (default 3)")
parser.add_argument("--msgs", type=Path, help="mrtwin_msgs .msg directory, for bags without schemas")
parser.add_argument("--json", action="store_true", help="end with a one-line JSON summary")
args = parser.parse_args()

# Only used when the bag has no definitions of its own.
fallback = get_typestore(Stores.ROS2_HUMBLE)
if args.msgs:
    for path in sorted(args.msgs.glob("*.msg")):
        fallback.register(get_types_from_msg(path.read_text(), f"mrtwin_msgs/msg/{path.stem}"))
LEVELS = ["OK", "WARN", "ERROR", "STALE"]


def describe(msgtype, msg):
    """One line for the mrtwin topics; None for the others."""
    if msgtype == "mrtwin_msgs/msg/DamperSample":
        return (f"x {msg.displacement * 1e3:+7.2f} mm  v {msg.velocity:+.3f} m/s  "
                f"F {msg.force:+8.1f} N  I {msg.current:.2f} A")
    if msgtype == "mrtwin_msgs/msg/TwinOutput":
        return (f"predicted {msg.predicted_force:+8.1f} N  measured {msg.measured_force:+8.1f} N  "
                f"residual {msg.residual:+6.1f} N  health {LEVELS[msg.health_level]}  ({msg.model_id})")
    if msgtype == "mrtwin_msgs/msg/YieldEstimate":
        return f"tau0 {msg.tau0 / 1e3:.2f} ± {msg.tau0_std / 1e3:.2f} kPa at {msg.current:.2f} A"
    if msgtype == "diagnostic_msgs/msg/DiagnosticArray":
        return ", ".join(f"{s.name.split(': ', 1)[-1]} {LEVELS[s.level]}" for s in msg.status)
    return None


counts = Counter()
shown = Counter()
forces, levels = [], set()
with AnyReader([args.bag], default_typestore=fallback) as reader:
    print(f"{args.bag}: {reader.message_count} messages, {reader.duration * 1e-9:.3f} s")
    for conn in reader.connections:
        print(f"  {conn.topic:32} {conn.msgtype:38} {conn.msgcount:7} msgs")
    for conn, _, raw in reader.messages():
        counts[conn.topic] += 1
        msg = reader.deserialize(raw, conn.msgtype)
        if conn.msgtype == "mrtwin_msgs/msg/TwinOutput":
            forces.append(msg.predicted_force)
            levels.add(msg.health_level)
        if shown[conn.topic] < args.show and (line := describe(conn.msgtype, msg)):
            shown[conn.topic] += 1
            stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
            print(f"{conn.topic} t={stamp:.3f} s: {line}")
    expected = {conn.topic: conn.msgcount for conn in reader.connections}
    types = {conn.topic: conn.msgtype for conn in reader.connections}

print("read: " + ", ".join(f"{topic} {n}" for topic, n in sorted(counts.items())))
if args.json:
    print(json.dumps({"counts": counts, "metadata_counts": expected,
                      "types": types,
                      "outputs_finite": all(math.isfinite(f) for f in forces),
                      "health_levels": sorted(levels)}))
if counts != Counter(expected):
    raise SystemExit(f"error: messages read {dict(counts)} differ from the bag's counts {expected}")
