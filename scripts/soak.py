"""Soak of the live system (issue 15): stand → twin → recorder over zenoh at 1 kHz for
30 minutes, a fault injected every minute, RSS / CPU / message counts logged.

    cargo build --release -p mrtwin && .venv/bin/python scripts/soak.py [--minutes 30] [--out DIR]

The faults, in turn (one per minute, starting at minute 1):
  stand-kill      kill -9 of the stand, restarted 2 s later (a publisher that dies)
  stand-silent    the stand stopped (SIGSTOP) for 5 s, then continued (a silent sensor)
  twin-kill       kill -9 of the twin, restarted 2 s later (a late joiner mid-stream)
  burst           the stand restarted for 10 s with 5 % duplicated and 5 % swapped samples
  twin-stall      the twin stopped (SIGSTOP) for 3 s, then continued (a scheduling stall)

The recorder (`mrtwin record`, zenoh listener) runs throughout and is stopped with SIGINT
at the end; the bag is then read with the python `mcap` and `rosbags` readers. Every 5 s
the RSS and CPU of each process are sampled from /proc. Output: a Markdown summary on
stdout (BENCHMARKS.md quotes it) and `soak.json` in --out with every sample.
"""
import argparse
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FAULTS = ["stand-kill", "stand-silent", "twin-kill", "burst", "twin-stall"]
RATE_HZ = 1000.0
PAGE = os.sysconf("SC_PAGE_SIZE")
TICK = os.sysconf("SC_CLK_TCK")


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def proc_stats(pid):
    """(RSS in MiB, CPU seconds) of a live process, or None."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        with open(f"/proc/{pid}/statm") as f:
            rss_pages = int(f.read().split()[1])
    except (FileNotFoundError, ProcessLookupError, IndexError):
        return None
    utime, stime = int(fields[11]), int(fields[12])
    return rss_pages * PAGE / 2**20, (utime + stime) / TICK


class Proc:
    """One mrtwin process, restartable; its lives are kept for the summary."""

    def __init__(self, name, args, log_dir):
        self.name, self.args, self.log_dir = name, args, log_dir
        self.p, self.lives = None, []

    def start(self, args=None):
        log = open(os.path.join(self.log_dir, f"{self.name}{len(self.lives)}.log"), "w")
        self.p = subprocess.Popen(args or self.args, stdout=log, stderr=subprocess.STDOUT)
        self.lives.append({"pid": self.p.pid, "start": time.time(), "end": None,
                           "how": None, "rss_mib": [], "cpu_s": 0.0})

    def alive(self):
        return self.p is not None and self.p.poll() is None

    def sample(self):
        if not self.alive():
            return
        st = proc_stats(self.p.pid)
        if st:
            life = self.lives[-1]
            life["rss_mib"].append((round(time.time() - life["start"], 1), round(st[0], 2)))
            life["cpu_s"] = st[1]

    def stop(self, sig, how):
        if not self.alive():
            return
        self.sample()
        self.p.send_signal(sig)
        try:
            self.p.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.p.kill()
            self.p.wait()
        self.lives[-1]["end"] = time.time()
        self.lives[-1]["how"] = how
        self.lives[-1]["rc"] = self.p.returncode


def params(path, text):
    with open(path, "w") as f:
        f.write(text)
    return path


def read_bag(bag):
    """Per-topic counts, and per diagnostics message (stamp, level of `sensor stream`)."""
    from mcap.reader import make_reader
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    counts, stream = {}, []
    for name in sorted(os.listdir(bag)):
        if not name.endswith(".mcap"):
            continue
        with open(os.path.join(bag, name), "rb") as f:
            for _, channel, message in make_reader(f).iter_messages():
                counts[channel.topic] = counts.get(channel.topic, 0) + 1
                if channel.topic == "/diagnostics":
                    d = ts.deserialize_cdr(message.data, "diagnostic_msgs/msg/DiagnosticArray")
                    for s in d.status:
                        if s.name.endswith("sensor stream"):
                            stream.append((message.log_time / 1e9, int(s.level)))
    return counts, stream


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=30.0)
    ap.add_argument("--bin", default=os.path.join(ROOT, "target", "release", "mrtwin"))
    ap.add_argument("--out", default=None, help="directory for logs, bag and soak.json")
    a = ap.parse_args()
    out = a.out or tempfile.mkdtemp(prefix="mrtwin-soak-")
    os.makedirs(out, exist_ok=True)
    port, damper = free_port(), f"soak{os.getpid()}"
    zen = (f"    zenoh:\n      multicast_scouting: false\n"
           f"      connect: [\"tcp/127.0.0.1:{port}\"]\n")
    twin_p = params(os.path.join(out, "twin.yaml"),
                    f"mrtwin_twin:\n  ros__parameters:\n    damper: {damper}\n"
                    f"    model: two-chamber\n    transports: [zenoh]\n    input: zenoh\n"
                    f"    control_service: false\n" + zen)
    stand_text = (f"mrtwin_stand:\n  ros__parameters:\n    damper: {damper}\n"
                  f"    model: two-chamber\n    transports: [zenoh]\n    rate_hz: {RATE_HZ}\n"
                  f"    currents_a: [0.5, 1.0, 1.5]\n    frequencies_hz: [1.0, 2.0]\n"
                  f"    segment_duration_s: 10.0\n    noise_n: 5.0\n" + zen)
    stand_p = params(os.path.join(out, "stand.yaml"), stand_text)
    burst_p = params(os.path.join(out, "burst.yaml"), stand_text.replace(
        "    noise_n: 5.0\n", "    noise_n: 5.0\n    faults:\n      duplicate_probability: 0.05\n"
        "      swap_probability: 0.05\n"))
    rec_p = params(os.path.join(out, "recorder.yaml"),
                   f"/**:\n  ros__parameters:\n    damper: {damper}\n    zenoh:\n"
                   f"      multicast_scouting: false\n      listen: [\"tcp/127.0.0.1:{port}\"]\n")
    bag = os.path.join(out, "bag")
    b = a.bin
    recorder = Proc("recorder", [b, "record", "--out", bag, "--transport", "zenoh",
                                 "--ros-args", "--params-file", rec_p], out)
    twin = Proc("twin", [b, "node", "--ros-args", "--params-file", twin_p], out)
    stand = Proc("stand", [b, "stand", "--ros-args", "--params-file", stand_p], out)
    burst_args = [b, "stand", "--ros-args", "--params-file", burst_p]
    procs = [recorder, twin, stand]
    recorder.start()
    time.sleep(1.0)
    twin.start()
    time.sleep(1.0)
    stand.start()
    t0 = time.time()
    end = t0 + 60.0 * a.minutes
    events, next_sample, minute = [], t0, 1
    pending = []  # (time, action)

    def fault(kind):
        now = time.time()
        events.append({"t_s": round(now - t0, 2), "fault": kind})
        if kind == "stand-kill":
            stand.stop(signal.SIGKILL, "kill -9")
            pending.append((now + 2.0, lambda: stand.start()))
        elif kind == "stand-silent":
            os.kill(stand.p.pid, signal.SIGSTOP)
            pending.append((now + 5.0, lambda: os.kill(stand.p.pid, signal.SIGCONT)))
        elif kind == "twin-kill":
            twin.stop(signal.SIGKILL, "kill -9")
            pending.append((now + 2.0, lambda: twin.start()))
        elif kind == "burst":
            stand.stop(signal.SIGINT, "stopped for the burst")
            stand.start(burst_args)
            pending.append((now + 10.0, lambda: (stand.stop(signal.SIGINT, "burst over"),
                                                 stand.start())))
        elif kind == "twin-stall":
            os.kill(twin.p.pid, signal.SIGSTOP)
            pending.append((now + 3.0, lambda: os.kill(twin.p.pid, signal.SIGCONT)))

    while time.time() < end:
        now = time.time()
        for item in [p for p in pending if p[0] <= now]:
            pending.remove(item)
            item[1]()
        if now >= t0 + 60.0 * minute and minute < a.minutes:
            fault(FAULTS[(minute - 1) % len(FAULTS)])
            minute += 1
        if now >= next_sample:
            for p in procs:
                p.sample()
            next_sample += 5.0
        for p in (twin, stand, recorder):
            if p.p is not None and p.p.poll() is not None and p.lives[-1]["end"] is None:
                p.lives[-1].update(end=time.time(), how="exited by itself", rc=p.p.returncode)
        time.sleep(0.05)
    for at, action in sorted(pending, key=lambda x: x[0]):
        action()
    stand.stop(signal.SIGINT, "end of soak")
    time.sleep(1.0)
    twin.stop(signal.SIGINT, "end of soak")
    time.sleep(1.5)
    recorder.stop(signal.SIGINT, "end of soak")
    counts, stream = read_bag(bag)

    t_end = time.time()
    stand_alive = sum((l["end"] or t_end) - l["start"] for l in stand.lives)
    silent = 5.0 * sum(1 for e in events if e["fault"] == "stand-silent")
    samples = counts.get(f"/{damper}/sensor/sample", 0) or next(
        (n for k, n in counts.items() if k.endswith("sensor/sample")), 0)
    outputs = next((n for k, n in counts.items() if k.endswith("twin/output")), 0)
    # STALE episodes of the twin's `sensor stream` check, and whether each recovered.
    episodes, state = [], None
    for t, level in stream:
        if t > end:
            break  # the stand stops at the end of the soak
        if level == 3 and state is None:
            state = t
        elif level == 0 and state is not None:
            episodes.append((round(state - t0, 1), round(t - t0, 1)))
            state = None
    summary = {
        "minutes": a.minutes, "rate_hz": RATE_HZ, "faults": events, "bag_counts": counts,
        "stand_alive_s": stand_alive, "stand_silent_s": silent,
        # A stopped stand catches up when continued (its stamps run on the wall clock), so
        # the silence costs no samples; a killed stand's backlog is lost.
        "expected_samples": RATE_HZ * stand_alive,
        "recorded_samples": samples, "recorded_twin_outputs": outputs,
        "stale_episodes": episodes, "stale_unrecovered_since": state and round(state - t0, 1),
        "processes": {p.name: p.lives for p in procs},
    }
    with open(os.path.join(out, "soak.json"), "w") as f:
        json.dump(summary, f, indent=1)

    print(f"## Soak: {a.minutes:g} min at {RATE_HZ:g} Hz, {len(events)} faults ({out})\n")
    print("| process | lives | RSS after 60 s of each life (MiB) | RSS at the end of each life (MiB) | CPU (s per minute alive) |")
    print("|---|---|---|---|---|")
    for p in procs:
        early = [next((r for s, r in l["rss_mib"] if s >= 60), None) for l in p.lives]
        last = [l["rss_mib"][-1][1] if l["rss_mib"] else None for l in p.lives]
        alive = sum(((l["end"] or time.time()) - l["start"]) for l in p.lives)
        cpu = sum(l["cpu_s"] for l in p.lives)
        fmt = lambda v: ", ".join("—" if x is None else f"{x:.1f}" for x in v)
        print(f"| {p.name} | {len(p.lives)} | {fmt(early)} | {fmt(last)} | {60 * cpu / alive:.2f} |")
    print()
    print(f"- sensor samples: {samples} recorded of {summary['expected_samples']:.0f} expected "
          f"({RATE_HZ:g} Hz × {stand_alive:.0f} s of stand lives; its {silent:.0f} s stopped are "
          f"caught up on SIGCONT)")
    print(f"- twin outputs recorded: {outputs} ({outputs / max(samples, 1):.4f} per sample; the "
          f"twin is down 2 s per kill and stalled 3 s per stall)")
    print(f"- `sensor stream` STALE episodes (start → back to OK, s): {episodes}"
          + (f"; not recovered since {summary['stale_unrecovered_since']} s"
             if state is not None else ""))
    print(f"- bag topics: {counts}")
    unclean = [(p.name, l["how"], l.get("rc")) for p in procs for l in p.lives
               if l["how"] == "exited by itself"]
    print(f"- processes that exited by themselves: {unclean or 'none'}")
    return 0 if not unclean and state is None else 1


if __name__ == "__main__":
    sys.exit(main())
