"""rclpy AsyncParameterClient against `mrtwin stand` (cli/tests/ros2_parameters.rs): list by
section, get, describe, refused sets, and two good sets that must show in the stand's
DamperSample stream (mrtwin_msgs, built natively) from the next sample: a new programme
(one current, 1.75 A) and a 50 kN load-cell offset of its model. Prints one JSON line.

"From the next sample" is read off the samples' stamps, not their arrival: the stand stamps
sample k with its scheduled wall-clock time and makes it no earlier, so a sample stamped after
this client had the answer (same machine, same clock) was made after the set was stored and
must carry it. Samples made before it may still arrive after the answer (a backlog in this
process or in flight); they are counted, not bounded."""
import json, sys, time
import rclpy
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import QoSProfile, ReliabilityPolicy
from mrtwin_msgs.msg import DamperSample

target, ns = sys.argv[1], sys.argv[2]
rclpy.init()
node = rclpy.create_node("mrtwin_stand_param_probe")
client = AsyncParameterClient(node, target)
out = {}
samples = []  # [phase, current, force, stamp]; phase: 0 before the sets, 1 while a set is answered, 2 after
phase = [0]
node.create_subscription(DamperSample, f"{ns}/sensor/sample",
                         lambda m: samples.append([phase[0], m.current, m.force,
                                                           m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec]),
                         QoSProfile(depth=1000, reliability=ReliabilityPolicy.BEST_EFFORT))
def wait(request, what):
    return ask(node, request, what)  # ros2_parameters_ask.py, prepended
def spin(seconds):
    end = time.time() + seconds
    while time.time() < end:
        rclpy.spin_once(node, timeout_sec=0.05)
out["services"] = client.wait_for_services(timeout_sec=30)
prefixes = ["currents_a", "noise_n", "faults", "two_chamber", "rate_hz", "seed", "damper"]
names = [n for p in prefixes for n in wait(lambda: client.list_parameters([p], 0), "list " + p).result.names]
out["has"] = {n: n in names for n in ["currents_a", "noise_n", "faults.drop_probability",
                                      "two_chamber.load_cell_offset_n", "rate_hz", "seed", "damper"]}
def get(name):
    v = wait(lambda: client.get_parameters([name]), "get").values[0]
    return {"type": v.type, "double": v.double_value, "doubles": list(v.double_array_value)}
answered = [None]  # wall-clock time at which the last set's answer was in hand
def set_(name, value):
    phase[0] = 1
    r = wait(lambda: client.set_parameters([Parameter(name, value=value)]), "set").results[0]
    answered[0] = time.time()
    phase[0] = 2
    return {"ok": r.successful, "reason": r.reason}
out["currents_before"] = get("currents_a")["doubles"]
out["described"] = wait(lambda: client.describe_parameters(["noise_n"]), "describe").descriptors[0].name
out["noise_before"] = get("noise_n")["double"]
out["bad_noise"] = set_("noise_n", -1.0)
out["bad_rate"] = set_("rate_hz", 2000.0)
out["bad_model"] = set_("model", "magic")
out["noise_after_bad"] = get("noise_n")["double"]
phase[0] = 0
spin(2)
before = [s for s in samples if s[0] == 0]
out["before"] = len(before)
out["currents_seen_before"] = sorted({s[1] for s in before})
del samples[:]
out["currents_set"] = set_("currents_a", [1.75])
spin(1.5)
after = [s[1] for s in samples if s[0] == 2]
moved = [c == 1.75 for c in after]
out["after"] = len(after)
out["old_after_set"] = moved.index(True) if True in moved else len(after)  # arrived late
out["old_stamped_after_answer"] = sum(1 for s in samples if s[1] != 1.75 and s[3] > answered[0])
out["stamped_after_answer"] = sum(1 for s in samples if s[3] > answered[0])
out["new_then_all"] = all(moved[moved.index(True):]) if True in moved else False
out["currents_get"] = get("currents_a")["doubles"]
offset = get("two_chamber.load_cell_offset_n")["double"]
spin(0.5)
out["old_force_max"] = max(abs(s[2]) for s in samples)
del samples[:]
out["offset_set"] = set_("two_chamber.load_cell_offset_n", offset + 50000.0)
spin(1.5)
shifted = [s[2] > 30000.0 for s in samples if s[0] == 2]
out["after_offset"] = len(shifted)
out["unshifted_after_set"] = shifted.index(True) if True in shifted else len(shifted)  # arrived late
out["unshifted_stamped_after_answer"] = sum(1 for s in samples if s[2] <= 30000.0 and s[3] > answered[0])
out["stamped_after_offset_answer"] = sum(1 for s in samples if s[3] > answered[0])
out["shifted_then_all"] = all(shifted[shifted.index(True):]) if True in shifted else False
print(json.dumps(out))
node.destroy_node()
rclpy.shutdown()
