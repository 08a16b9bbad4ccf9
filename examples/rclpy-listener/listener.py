#!/usr/bin/env python3
"""Listen to the mrtwin twin node over ROS 2 with stock rclpy (Fast DDS, nothing of mrtwin built).

Subscribes to <namespace>/twin/predicted_force (std_msgs/Float64) and /diagnostics
(diagnostic_msgs/DiagnosticArray); prints the predicted force about once a second and, on
every diagnostics array, the level of each health check and the residual RMS the twin
reports. Exits 0 once --count forces have arrived, 1 when --timeout passes first.
"""
import argparse
import json
import math
import os
import sys
import time

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--domain-id", type=int, default=int(os.environ.get("ROS_DOMAIN_ID", "0")),
                    help="ROS domain id (default: $ROS_DOMAIN_ID or 0)")
parser.add_argument("--namespace", default="/", help="namespace of the twin node (default: /)")
parser.add_argument("--count", type=int, default=3000, help="stop after this many forces")
parser.add_argument("--timeout", type=float, default=30.0, help="give up after this many seconds")
parser.add_argument("--json", action="store_true", help="end with a one-line JSON summary")
args = parser.parse_args()

os.environ.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
import rclpy  # noqa: E402 (after the RMW choice)
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from std_msgs.msg import Float64  # noqa: E402

LEVELS = ["OK", "WARN", "ERROR", "STALE"]
forces = []
health = {}  # check name -> level
residual_rms = math.nan
diagnostics = 0


def on_force(msg):
    forces.append(msg.data)
    if len(forces) % 1000 == 1:
        print(f"force #{len(forces)}: {msg.data:9.1f} N", flush=True)


def on_diagnostics(msg):
    global residual_rms, diagnostics
    diagnostics += 1
    for status in msg.status:
        # `byte` fields are bytes of length 1 in rclpy
        level = status.level[0] if isinstance(status.level, bytes) else int(status.level)
        health[status.name] = level
        if status.name.endswith("prediction residual"):
            values = {kv.key: kv.value for kv in status.values}
            residual_rms = float(values.get("rms_n", "nan"))
    checks = ", ".join(f"{name.split(': ', 1)[-1]} {LEVELS[lvl] if lvl < 4 else lvl}"
                       for name, lvl in health.items())
    print(f"health: {checks} | residual RMS {residual_rms:.1f} N", flush=True)


rclpy.init(domain_id=args.domain_id)
node = rclpy.create_node("mrtwin_listener")
ns = args.namespace.rstrip("/")
# The twin publishes reliable, keep last 1000 (docs/ros2.md); match it.
node.create_subscription(Float64, f"{ns}/twin/predicted_force", on_force,
                         QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
node.create_subscription(DiagnosticArray, "/diagnostics", on_diagnostics, 10)
print(f"listening on ROS domain {args.domain_id}: {ns}/twin/predicted_force, /diagnostics",
      flush=True)
deadline = time.monotonic() + args.timeout
while len(forces) < args.count and time.monotonic() < deadline:
    rclpy.spin_once(node, timeout_sec=0.1)
node.destroy_node()
rclpy.shutdown()

finite = [f for f in forces if math.isfinite(f)]
print(f"received {len(forces)} predicted forces ({len(finite)} finite, "
      f"{min(finite, default=math.nan):.1f} to {max(finite, default=math.nan):.1f} N), "
      f"{diagnostics} diagnostics arrays")
if args.json:
    print(json.dumps({"forces": len(forces), "finite": len(finite),
                      "min_n": min(finite, default=None), "max_n": max(finite, default=None),
                      "diagnostics": diagnostics, "levels": health,
                      "residual_rms_n": residual_rms if math.isfinite(residual_rms) else None}))
if len(forces) < args.count:
    print(f"error: only {len(forces)} of {args.count} forces within {args.timeout} s "
          "(is the twin running on this domain with ros2 among its transports?)", file=sys.stderr)
    sys.exit(1)
