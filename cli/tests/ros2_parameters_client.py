"""rclpy AsyncParameterClient against an mrtwin twin (cli/tests/ros2_parameters.rs): list by
section, get, describe, bad and good sets, and with `force` a load-cell offset that must
show in /twin/output (mrtwin_msgs, built natively) from the next sample. Prints one JSON line.

"From the next sample" is read off the outputs' stamps (each its sample's): the stand makes a
sample no earlier than its scheduled wall-clock stamp and the twin steps it after that, so an
output stamped after this client had the answer (same machine, same clock) was stepped after
the set was stored and must carry it. Outputs stepped before it may still arrive after the
answer (a backlog in this process or in flight); they are counted, not bounded."""
import json, sys, time
import rclpy
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient

target, check_force = sys.argv[1], sys.argv[2] == "force"
rclpy.init()
node = rclpy.create_node("mrtwin_param_probe")
client = AsyncParameterClient(node, target)
out = {}
def wait(request, what):
    return ask(node, request, what)  # ros2_parameters_ask.py, prepended
out["services"] = client.wait_for_services(timeout_sec=30)
# By section: the reply to an unprefixed list (~95 names, > one datagram) is fragmented by
# RustDDS and never reaches a Fast DDS client (see docs/node.md, "ROS 2 parameters").
names = [n for p in ["health", "estimator", "two_chamber", "model", "damper", "stale_after_s"] for n in wait(lambda: client.list_parameters([p], 0), "list " + p).result.names]
out["names"] = len(names)
out["has"] = {n: n in names for n in ["health.residual.warn", "estimator.settings.memory_s",
                                      "two_chamber.bulk_modulus_pa", "model", "damper"]}
def get(name):
    v = wait(lambda: client.get_parameters([name]), "get").values[0]
    return {"type": v.type, "double": v.double_value, "string": v.string_value}
out["stale_before"] = get("stale_after_s")
d = wait(lambda: client.describe_parameters(["stale_after_s"]), "describe").descriptors[0]
out["described"] = d.name
def set_(name, value):
    r = wait(lambda: client.set_parameters([Parameter(name, value=value)]), "set").results[0]
    return {"ok": r.successful, "reason": r.reason}
out["bad"] = set_("stale_after_s", -1.0)
out["bad_type"] = set_("stale_after_s", "soon")
out["bad_effect"] = set_("effects", "warp_drive")
out["stale_after_bad"] = get("stale_after_s")
out["good"] = set_("health.residual.warn", 0.07)
out["warn_after"] = get("health.residual.warn")
if check_force:
    from mrtwin_msgs.msg import TwinOutput
    forces = []  # [predicted force, stamp]
    node.create_subscription(TwinOutput, "/twin/output", lambda m: forces.append(
        [m.predicted_force, m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec]), 1000)
    end = time.time() + 3
    while time.time() < end:
        rclpy.spin_once(node, timeout_sec=0.05)
    offset = get("two_chamber.load_cell_offset_n")["double"]
    # Counted after the get: the forces that arrive while it is answered are not after the set.
    before = len(forces)
    out["offset_set"] = set_("two_chamber.load_cell_offset_n", offset + 50000.0)
    answered = time.time()
    # 2 s, and on a loaded machine longer: until 1500 outputs stamped after the answer have
    # arrived (the test asks for more than 1000), at most 15 s.
    end, limit = answered + 2, answered + 15
    while time.time() < end or (
            time.time() < limit and sum(1 for _, t in forces if t > answered) < 1500):
        rclpy.spin_once(node, timeout_sec=0.05)
    old, after = forces[:before], forces[before:]
    shifted = [f > 30000.0 for f, _ in after]
    out["before"] = before
    out["after"] = len(after)
    out["old_max"] = max(abs(f) for f, _ in old) if old else None
    # outputs stepped before the set was taken that arrived after the answer
    out["unshifted_after_set"] = shifted.index(True) if True in shifted else len(after)
    out["stamped_after_answer"] = sum(1 for _, t in forces if t > answered)
    out["unshifted_stamped_after_answer"] = sum(1 for f, t in forces if f <= 30000.0 and t > answered)
    out["shifted_then_all"] = all(shifted[shifted.index(True):]) if True in shifted else False
print(json.dumps(out))
node.destroy_node()
rclpy.shutdown()
