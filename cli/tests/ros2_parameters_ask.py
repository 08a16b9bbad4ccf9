"""Prepended to the rclpy parameter clients (cli/tests/ros2_parameters.rs): one request,
answered or sent again."""
import rclpy


def ask(node, request, what, tries=3, each_s=10):
    """Sends `request()` and returns its answer; sends it again when none comes within each_s.
    A reply sent before the server's reply writer has matched this client's reply reader is
    lost (a DDS discovery race that wait_for_services does not close: it sees only the request
    side), so under load the first request can go unanswered. Every request here is idempotent."""
    for _ in range(tries):
        fut = request()
        rclpy.spin_until_future_complete(node, fut, timeout_sec=each_s)
        if fut.done():
            return fut.result()
    raise SystemExit(f"no answer to {what} in {tries} tries of {each_s} s")
