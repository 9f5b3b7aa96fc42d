"""Plain rclpy nodes for `--backend rclpy`: the ROS end of each scenario, and the rclpy ceiling.

Run with the ROS environment's Python (`.venv-ros/bin/python -m tests.bench.rosnodes ROLE`);
it imports nothing of the harness but the stdlib and rclpy. Every role prints one `ready` line
on stdout once it serves, then:

    serve     /add_two_ints as test_msgs/srv/BasicTypes (example_interfaces is not on PyPI):
              int64_value = int64_value + int32_value; SingleThreadedExecutor; runs until stopped.
    image     a 640x480 rgb8 sensor_msgs/msg/Image on --topic at --rate Hz (absolute schedule),
              its sequence number in header.stamp.sec; answers each stdin line `count` with
              the number published so far and its CLOCK_MONOTONIC time.
    ceiling   the same traffic as the websocket scenarios between plain rclpy nodes in this one
              process (SingleThreadedExecutor, no websocket): one JSON command per stdin line,
              one JSON result per stdout line (see CEILING).
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
import time

STAMP_LEN = 32  # as tests/bench/client.py: 12 digits of sequence, 20 of CLOCK_MONOTONIC ns
STALL_S = 1.0
SERVICE = "/add_two_ints"
# service QoS depth of the server node and the ceiling client: the default 10 loses calls at 32 in flight
DEPTH = 64


def reply(doc: dict) -> None:
    sys.stdout.write(json.dumps(doc) + "\n")
    sys.stdout.flush()


def percentile(values: list, q: float):
    if not values:
        return None
    values = sorted(values)
    return values[min(len(values) - 1, max(0, round(q / 100 * (len(values) - 1))))]


def ms(ns) -> float | None:
    return None if ns is None else ns / 1e6


def stamped(seq: int, size: int) -> str:
    return "%012d%020d" % (seq, time.monotonic_ns()) + "x" * (size - STAMP_LEN)


def read_stamp(data: str) -> tuple[int, int]:
    return int(data[:12]), int(data[12:STAMP_LEN])


class Graph:
    """One rclpy context, one SingleThreadedExecutor, nodes made on demand."""

    def __init__(self) -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        rclpy.init()
        self.rclpy = rclpy
        self.executor = SingleThreadedExecutor()
        self.nodes = []

    def node(self, name: str):
        node = self.rclpy.create_node(name, start_parameter_services=False, enable_rosout=False)
        self.executor.add_node(node)
        self.nodes.append(node)
        return node

    def drop(self, node) -> None:
        self.executor.remove_node(node)
        self.nodes.remove(node)
        node.destroy_node()

    def spin_once(self, timeout: float) -> None:
        self.executor.spin_once(timeout_sec=max(0.0, timeout))

    def spin_until(self, done, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while not done():
            if time.monotonic() > deadline:
                return False
            self.spin_once(0.05)
        return True


def qos(depth: int):
    from rclpy.qos import QoSProfile

    return QoSProfile(depth=depth)


# ---- long-running nodes -------------------------------------------------------------------------


def serve(graph: Graph) -> None:
    from test_msgs.srv import BasicTypes

    def add(request, response):
        response.int64_value = request.int64_value + request.int32_value
        return response

    node = graph.node("bench_add_two_ints")
    node.create_service(BasicTypes, SERVICE, add, qos_profile=qos(DEPTH))
    reply({"ready": SERVICE})
    graph.executor.spin()


def image_message(width: int = 640, height: int = 480):
    import os

    from sensor_msgs.msg import Image

    msg = Image(height=height, width=width, encoding="rgb8", step=width * 3)
    msg.header.frame_id = "camera"
    msg.data = os.urandom(width * height * 3)
    return msg


def image(graph: Graph, topic: str, rate: float) -> None:
    from sensor_msgs.msg import Image

    node = graph.node("bench_camera")
    pub = node.create_publisher(Image, topic, qos(10))
    msg = image_message()
    sent = [0]

    def answer() -> None:
        for line in sys.stdin:
            if line.strip() == "count":
                reply({"count": sent[0], "t": time.monotonic()})

    threading.Thread(target=answer, daemon=True).start()
    reply({"ready": topic})
    period = 1.0 / rate
    next_at = time.monotonic()
    while graph.rclpy.ok():  # until SIGINT shuts the context down
        delay = next_at - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        msg.header.stamp.sec = sent[0]
        if not graph.rclpy.ok():
            break
        pub.publish(msg)
        sent[0] += 1
        next_at += period


# ---- the rclpy ceiling --------------------------------------------------------------------------


def ceiling_throughput(graph: Graph, size: int, window: int, duration: float) -> dict:
    """One publisher node and one subscriber node in this process; W messages in flight."""
    from std_msgs.msg import String

    topic = f"/bench/ceil_tp_{time.monotonic_ns()}"
    pub_node, sub_node = graph.node("bench_ceil_pub"), graph.node("bench_ceil_sub")
    state = {"inflight": 0, "any": 0, "measure_from": None, "count": 0, "progress": time.monotonic()}
    lat: list[int] = []

    def on_msg(msg) -> None:
        now = time.monotonic_ns()
        state["inflight"] = max(0, state["inflight"] - 1)
        state["any"] += 1
        state["progress"] = time.monotonic()
        seq, sent = read_stamp(msg.data)
        if state["measure_from"] is not None and seq >= state["measure_from"]:
            lat.append(now - sent)
            state["count"] += 1

    try:
        depth = max(10, 2 * window)
        pub = pub_node.create_publisher(String, topic, qos(depth))
        sub_node.create_subscription(String, topic, on_msg, qos(depth))
        seq = 0
        deadline = time.monotonic() + 20
        while not state["any"]:  # warm-up: until discovery lets one through
            if time.monotonic() > deadline:
                raise TimeoutError("no message delivered during warm-up")
            pub.publish(String(data=stamped(seq, size)))
            seq += 1
            graph.spin_once(0.02)
        graph.spin_until(lambda: False, 0.05)
        state["inflight"], state["measure_from"], lost = 0, seq, 0
        first, t0, cpu0 = seq, time.monotonic(), time.process_time()
        end = t0 + duration
        while time.monotonic() < end:
            while state["inflight"] < window:
                pub.publish(String(data=stamped(seq, size)))
                seq += 1
                state["inflight"] += 1
            graph.spin_once(STALL_S / 4)
            if time.monotonic() - state["progress"] > STALL_S:  # the window was lost
                lost += state["inflight"]
                state["inflight"], state["progress"] = 0, time.monotonic()
        elapsed, cpu = time.monotonic() - t0, time.process_time() - cpu0
        count = state["count"]
        graph.spin_until(lambda: state["inflight"] == 0, STALL_S)
    finally:
        graph.drop(pub_node)
        graph.drop(sub_node)
    sent = seq - first
    return {
        "msg_per_s": count / elapsed,
        "mib_per_s": count * size / elapsed / 2**20,
        "lat_p50_ms": ms(percentile(lat, 50)),
        "lat_p95_ms": ms(percentile(lat, 95)),
        "lat_p99_ms": ms(percentile(lat, 99)),
        "delivered_pct": 100 * len(lat) / sent if sent else None,
        "messages": len(lat),
        "cpu_s": cpu,
        "window_s": elapsed,
    }


def ceiling_fanout(graph: Graph, subscribers: int, rate: float, size: int, duration: float) -> dict:
    """One publisher node at `rate` Hz and one node with `subscribers` subscriptions, in this process."""
    from std_msgs.msg import String

    topic = f"/bench/ceil_fan_{time.monotonic_ns()}"
    nodes = [graph.node("bench_ceil_fan_pub"), graph.node("bench_ceil_fan_sub")]
    got = [0] * subscribers
    lat: list[int] = []
    window = {"first": None, "last": None}

    def callback(index: int):
        def on_msg(msg) -> None:
            now = time.monotonic_ns()
            got[index] += 1
            seq, sent = read_stamp(msg.data)
            if window["first"] is not None and seq >= window["first"] and (
                    window["last"] is None or seq <= window["last"]):
                lat.append(now - sent)
        return on_msg

    try:
        pub = nodes[0].create_publisher(String, topic, qos(10))
        for i in range(subscribers):
            nodes[1].create_subscription(String, topic, callback(i), qos(10))
        seq = 0
        deadline = time.monotonic() + 30
        while not all(got):
            if time.monotonic() > deadline:
                raise TimeoutError("subscribers got no message during warm-up")
            pub.publish(String(data=stamped(seq, size)))
            seq += 1
            graph.spin_until(lambda: False, 0.05)
        graph.spin_until(lambda: False, 0.1)
        window["first"], first = seq, seq
        period = 1.0 / rate
        t0, cpu0 = time.monotonic(), time.process_time()
        next_at, end = t0, t0 + duration
        while next_at < end:
            while time.monotonic() < next_at:
                graph.spin_once(next_at - time.monotonic())
            pub.publish(String(data=stamped(seq, size)))
            seq += 1
            next_at += period
        window["last"] = seq - 1
        expected = subscribers * (seq - first)
        graph.spin_until(lambda: len(lat) >= expected, 2.0)
        cpu, elapsed = time.process_time() - cpu0, time.monotonic() - t0
    finally:
        for node in nodes:
            graph.drop(node)
    return {
        "delivered_pct": 100 * len(lat) / expected if expected else None,
        "lat_p50_ms": ms(percentile(lat, 50)),
        "lat_p95_ms": ms(percentile(lat, 95)),
        "published_hz": (seq - first) / duration,
        "messages": len(lat),
        "cpu_s": cpu,
        "window_s": elapsed,
    }


def ceiling_services(graph: Graph, concurrency: int, duration: float) -> dict:
    """A client node here calling the `serve` node, `concurrency` calls in flight."""
    from test_msgs.srv import BasicTypes

    node = graph.node("bench_ceil_client")
    lat: list[int] = []
    state = {"pending": 0, "failed": 0, "stop_at": None}
    try:
        client = node.create_client(BasicTypes, SERVICE, qos_profile=qos(DEPTH))
        if not client.wait_for_service(timeout_sec=20):
            raise TimeoutError(f"{SERVICE} is not served")

        def call() -> None:
            request = BasicTypes.Request(int64_value=2, int32_value=3)
            sent = time.monotonic_ns()
            state["pending"] += 1

            def done(future) -> None:
                state["pending"] -= 1
                result = future.result()
                if result is not None and result.int64_value == 5:
                    lat.append(time.monotonic_ns() - sent)
                else:
                    state["failed"] += 1
                if state["stop_at"] is not None and time.monotonic() < state["stop_at"]:
                    call()

            client.call_async(request).add_done_callback(done)

        for _ in range(5):  # warm-up, one at a time
            call()
            if not graph.spin_until(lambda: state["pending"] == 0, 10):
                raise TimeoutError(f"{SERVICE} did not answer during warm-up")
        lat.clear()
        t0, cpu0 = time.monotonic(), time.process_time()
        state["stop_at"] = t0 + duration
        for _ in range(concurrency):
            call()
        graph.spin_until(lambda: state["pending"] == 0, duration + 10)
        elapsed, cpu = time.monotonic() - t0, time.process_time() - cpu0
        stuck = state["pending"]
    finally:
        graph.drop(node)
    return {
        "calls_per_s": len(lat) / elapsed,
        "lat_p50_ms": ms(percentile(lat, 50)),
        "lat_p95_ms": ms(percentile(lat, 95)),
        "lat_p99_ms": ms(percentile(lat, 99)),
        "failed": state["failed"] + stuck,
        "calls": len(lat),
        "cpu_s": cpu,
        "window_s": elapsed,
    }


def ceiling_images(graph: Graph, topic: str, subscribers: int, duration: float) -> dict:
    """`subscribers` subscriber nodes of the image topic (published by an `image` node)."""
    from sensor_msgs.msg import Image

    seqs: list[list[int]] = [[] for _ in range(subscribers)]
    nodes = []
    try:
        for i in range(subscribers):
            node = graph.node(f"bench_ceil_img{i}")
            nodes.append(node)
            node.create_subscription(Image, topic, lambda m, i=i: seqs[i].append(m.header.stamp.sec),
                                     qos(10))
        if not graph.spin_until(lambda: all(seqs), 20):
            raise TimeoutError("no image arrived during warm-up")
        graph.spin_until(lambda: False, 0.2)  # what queued during discovery
        first, base = max(s[-1] for s in seqs) + 1, [len(s) for s in seqs]
        t0, cpu0 = time.monotonic(), time.process_time()
        graph.spin_until(lambda: False, duration)
        elapsed, cpu = time.monotonic() - t0, time.process_time() - cpu0
        end, arrived = max(s[-1] for s in seqs) + 1, [len(s) - b for s, b in zip(seqs, base)]
        graph.spin_until(lambda: all(s[-1] >= end - 1 for s in seqs), 1.0)
    finally:
        for node in nodes:
            graph.drop(node)
    received = [sum(1 for n in s if first <= n < end) for s in seqs]
    return {"arrived": arrived, "received": received, "published": end - first, "cpu_s": cpu,
            "window_s": elapsed}


CEILING = {
    "throughput": lambda g, c: ceiling_throughput(g, c["size"], c["window"], c["duration"]),
    "fanout": lambda g, c: ceiling_fanout(g, c["subscribers"], c["rate"], c["size"], c["duration"]),
    "services": lambda g, c: ceiling_services(g, c["concurrency"], c["duration"]),
    "images": lambda g, c: ceiling_images(g, c["topic"], c["subscribers"], c["duration"]),
}


def ceiling(graph: Graph) -> None:
    reply({"ready": "ceiling"})
    for line in sys.stdin:
        if not line.strip():
            continue
        command = json.loads(line)
        try:
            reply({"result": CEILING[command["cmd"]](graph, command)})
        except Exception as exc:  # the harness records it, and the run goes on
            reply({"error": f"{type(exc).__name__}: {exc}"})


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m tests.bench.rosnodes", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("role", choices=["serve", "image", "ceiling"])
    p.add_argument("--topic", default="/bench/image")
    p.add_argument("--rate", type=float, default=30.0)
    args = p.parse_args(argv)
    from rclpy.executors import ExternalShutdownException

    graph = Graph()
    try:
        if args.role == "serve":
            serve(graph)
        elif args.role == "image":
            image(graph, args.topic, args.rate)
        else:
            ceiling(graph)
    except (KeyboardInterrupt, ExternalShutdownException):  # stopped with SIGINT
        pass
    return 0


if __name__ == "__main__":
    sys.exit(main())
