#!/usr/bin/env python3
"""Subscribe to the mrtwin twin node over zenoh and decode its CDR payloads with rosbags.

The twin puts the same CDR bytes on zenoh as on ROS 2, under mrtwin/<damper>/...:
twin/output (mrtwin_msgs/TwinOutput), twin/yield_estimate (mrtwin_msgs/YieldEstimate),
diagnostics (diagnostic_msgs/DiagnosticArray). The mrtwin_msgs types are registered from
the repository's msgs/msg/*.msg. Prints an output about once a second, every tenth yield
estimate and each diagnostics array. Exits 0 once --count outputs have arrived, 1 when
--timeout passes first.
"""
import argparse
import json
import math
import sys
import threading
from pathlib import Path

import zenoh
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--connect", default="tcp/127.0.0.1:7448",
                    help="zenoh endpoint of the twin (default: tcp/127.0.0.1:7448)")
parser.add_argument("--damper", default="rig1", help="damper name of the twin (default: rig1)")
parser.add_argument("--count", type=int, default=3000, help="stop after this many outputs")
parser.add_argument("--timeout", type=float, default=30.0, help="give up after this many seconds")
parser.add_argument("--msgs", type=Path, default=Path(__file__).resolve().parents[2] / "msgs" / "msg",
                    help="directory of the mrtwin_msgs .msg files (default: the repository's)")
parser.add_argument("--json", action="store_true", help="end with a one-line JSON summary")
args = parser.parse_args()

typestore = get_typestore(Stores.ROS2_HUMBLE)  # std_msgs, diagnostic_msgs, ...
for name in ["TwinOutput", "YieldEstimate"]:
    text = (args.msgs / f"{name}.msg").read_text()
    typestore.register(get_types_from_msg(text, f"mrtwin_msgs/msg/{name}"))
TYPES = {
    "twin/output": "mrtwin_msgs/msg/TwinOutput",
    "twin/yield_estimate": "mrtwin_msgs/msg/YieldEstimate",
    "diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
}
LEVELS = ["OK", "WARN", "ERROR", "STALE"]

lock = threading.Lock()
done = threading.Event()
outputs, estimates, diagnostics = [], [], []


def on_sample(sample):
    topic = str(sample.key_expr).split(f"mrtwin/{args.damper}/", 1)[-1]
    if topic not in TYPES:
        return  # sensor/sample, twin/predicted_force, clock: not shown here
    msg = typestore.deserialize_cdr(sample.payload.to_bytes(), TYPES[topic])
    with lock:
        if topic == "twin/output":
            outputs.append((msg.predicted_force, msg.residual, msg.health_level, msg.model_id))
            if len(outputs) % 1000 == 1:
                stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
                print(f"output #{len(outputs)} t={stamp:.3f} s: predicted {msg.predicted_force:9.1f} N, "
                      f"measured {msg.measured_force:9.1f} N, residual {msg.residual:7.1f} N, "
                      f"health {LEVELS[msg.health_level]} ({msg.model_id})", flush=True)
            if len(outputs) >= args.count:
                done.set()
        elif topic == "twin/yield_estimate":
            estimates.append((msg.current, msg.tau0))
            if len(estimates) % 10 == 1:
                print(f"yield estimate: tau0 {msg.tau0 / 1e3:.1f} ± {msg.tau0_std / 1e3:.1f} kPa "
                      f"at {msg.current:.2f} A", flush=True)
        else:
            diagnostics.append({s.name: s.level for s in msg.status})
            worst = max(s.level for s in msg.status)
            print(f"diagnostics: {len(msg.status)} checks, worst {LEVELS[worst]}", flush=True)


config = zenoh.Config()
config.insert_json5("mode", '"peer"')
config.insert_json5("connect/endpoints", json.dumps([args.connect]))
config.insert_json5("scouting/multicast/enabled", "false")
session = zenoh.open(config)
key = f"mrtwin/{args.damper}/**"
subscriber = session.declare_subscriber(key, on_sample)
print(f"subscribed to {key} via {args.connect}", flush=True)
done.wait(args.timeout)
subscriber.undeclare()
session.close()

with lock:
    forces = [o[0] for o in outputs]
    finite = all(math.isfinite(f) for f in forces)
    print(f"received {len(outputs)} outputs (all forces finite: {finite}), "
          f"{len(estimates)} yield estimates, {len(diagnostics)} diagnostics arrays")
    if args.json:
        print(json.dumps({
            "outputs": len(outputs), "forces_finite": finite,
            "residuals_finite": all(math.isfinite(o[1]) for o in outputs),
            "health_levels": sorted({o[2] for o in outputs}),
            "models": sorted({o[3] for o in outputs}),
            "yield_estimates": len(estimates),
            "tau0_pa": [e[1] for e in estimates if math.isfinite(e[1])][-1:],
            "diagnostics": diagnostics[-1:],
        }))
if len(outputs) < args.count:
    print(f"error: only {len(outputs)} of {args.count} outputs within {args.timeout} s "
          "(is the twin running with zenoh among its transports on this endpoint and damper?)",
          file=sys.stderr)
    sys.exit(1)
