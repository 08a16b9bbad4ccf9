"""A stock zenoh router (eclipse-zenoh from PyPI, a session in router mode) started from a
zenohd-style JSON5 configuration file, until SIGTERM or SIGINT: what `zenohd -c FILE` does
without its plugins, for machines without zenohd. Used by the fleet-over-routers test
(cli/tests/routers.rs); the deployment (docs/node.md, "Fleet across hosts") uses the same
files with zenohd.

    python scripts/zenoh-router.py launch-config/zenoh/router-central.json5
"""
import signal
import sys
import threading

import zenoh

conf = zenoh.Config.from_file(sys.argv[1])
session = zenoh.open(conf)
print(f"zenoh router {session.info.zid()} up ({sys.argv[1]})", flush=True)
done = threading.Event()
for sig in (signal.SIGTERM, signal.SIGINT):
    signal.signal(sig, lambda *_: done.set())
done.wait()
session.close()
