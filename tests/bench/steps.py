"""Where a publish's time goes on the rclpy backend, step by step:

    python -m tests.bench.steps [--sizes 64,1024,65536] [--windows 40]

A std_msgs/String publish takes this path through the gateway: the text frame's payload out of the
websocket reader, its UTF-8 check, JSON to an op, the op's rules, the message checked against its
type, CDR written, published to DDS and taken back by the gateway's own reader (Fast DDS delivers
inside the publish call), the CDR read, the frame encoded once for every subscriber, and the socket
write to a subscriber and the subscriber's read (the kernel's part, on loopback). Each step runs here
with the gateway's own functions, timed as the fastest of ``--windows`` windows of about 0.2 ms to
2 ms each: a figure that the machine's load moves far less than a rate (a busy machine preempts long
runs, not every short window). It is each step's cost with warm caches; the gateway's CPU per message
in ``python -m tests.bench --backend rclpy`` adds the loop, the rules' state and cache misses.

It needs rclpy (``.venv-ros``) and runs itself again in a loopback-only network namespace.
"""

from __future__ import annotations

import argparse
import os
import socket
import sys
import time

from tests.bench.rosgraph import isolated, reexec_isolated, ros_python

TOPIC = '/bench_steps'
TYPE = 'std_msgs/msg/String'


def best_us(fn, windows: int, budget_s: float = 0.002) -> float:
    """The fastest of ``windows`` timed windows of fn, in µs a call."""
    fn()
    t0 = time.perf_counter()
    fn()
    n = max(1, min(2000, int(budget_s / max(time.perf_counter() - t0, 1e-7))))
    best = float('inf')
    for _ in range(windows):
        t0 = time.perf_counter()
        for _ in range(n):
            fn()
        best = min(best, (time.perf_counter() - t0) / n)
    return best * 1e6


def steps(size: int):
    """(name, fn) per step of one String publish of ``size`` bytes, in the gateway's order."""
    import rclpy  # noqa: PLC0415 (the ROS environment's Python only)
    from std_msgs.msg import String  # noqa: PLC0415

    from gateway.backends.rclpy.types import Converter, RosDefinitions  # noqa: PLC0415
    from gateway.bridge.encode import frames  # noqa: PLC0415
    from gateway.web.fastio import frame_parts  # noqa: PLC0415
    from protocol.codec import decode_text  # noqa: PLC0415
    from protocol.convert import from_json  # noqa: PLC0415
    from protocol.ops import parse_op  # noqa: PLC0415

    frame = b'{"op":"publish","topic":"%s","msg":{"data":"%s"}}' % (TOPIC.encode(), b'x' * size)
    received = memoryview(bytearray(frame))     # picows's read buffer: the payload is copied out
    defs = RosDefinitions()
    msgdef, convert = defs.msg(TYPE), Converter(defs)
    write, read = convert.cdr_writer(String), convert.cdr_reader(String)
    rclpy.init()
    node = rclpy.create_node('bench_steps')
    pub = node.create_publisher(String, TOPIC, 10)
    reader = node.create_subscription(String, TOPIC, lambda _m: None, 10, raw=True).handle
    obj = decode_text(frame)
    op = parse_op(obj)
    msg = from_json(defs, msgdef, op.msg)
    cdr = write(msg)
    pub.publish(cdr)
    deadline = time.monotonic() + 10
    while (taken := reader.take_message(String, True)) is None:   # the reader matched the writer
        assert time.monotonic() < deadline, 'the reader never got the first message'
        time.sleep(0.01)
    assert taken[0] == cdr
    parts = frame_parts(frames({'op': 'publish', 'topic': TOPIC, 'msg': read(cdr)}))
    a, b = tcp_pair()
    view = memoryview(bytearray(256 * 1024))

    def publish_and_take():
        pub.publish(cdr)
        reader.take_message(String, True)

    def write_and_read():
        """One frame as the gateway writes it (header and payload in one sendmsg), read whole."""
        unsent, got, want = parts, 0, sum(map(len, parts))
        while got < want:
            if unsent:
                try:
                    sent = a.sendmsg(unsent)
                except BlockingIOError:
                    sent = 0
                unsent = remainder(unsent, sent)
            try:
                got += b.recv_into(view)
            except BlockingIOError:
                pass
    return [
        ('payload out of the reader (a copy)', received.tobytes),
        ('UTF-8 check (isascii)', frame.isascii),
        ('JSON -> dict (decode_text)', lambda: decode_text(frame)),
        ('dict -> op (parse_op)', lambda: parse_op(obj)),
        ('message checked (from_json)', lambda: from_json(defs, msgdef, op.msg)),
        ('dict -> CDR', lambda: write(msg)),
        ('DDS publish + own reader take', publish_and_take),
        ('CDR -> dict', lambda: read(cdr)),
        ('dict -> JSON frame (once for all)', lambda: frames({'op': 'publish', 'topic': TOPIC, 'msg': read(cdr)})),
        ('socket write + read (kernel, TCP loopback)', write_and_read),
    ], lambda: (node.destroy_node(), rclpy.shutdown(), a.close(), b.close())


def tcp_pair() -> tuple[socket.socket, socket.socket]:
    """A connected TCP pair on 127.0.0.1, non-blocking, without Nagle (as the gateway's sockets)."""
    with socket.create_server(('127.0.0.1', 0)) as server:
        a = socket.create_connection(server.getsockname())
        b, _ = server.accept()
    for s in (a, b):
        s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        s.setblocking(False)
    return a, b


def remainder(parts: list, sent: int) -> list:
    """What is left of parts once sent bytes went out."""
    out = []
    for part in parts:
        if sent >= len(part):
            sent -= len(part)
            continue
        out.append(memoryview(part)[sent:])
        sent = 0
    return out


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--sizes', default='64,1024,65536', help='String sizes in bytes (default 64,1024,65536)')
    p.add_argument('--windows', type=int, default=40, help='timed windows per step (default 40)')
    args = p.parse_args(argv)
    try:
        import rclpy  # noqa: F401, PLC0415
    except ImportError:
        os.execv(str(ros_python()), [str(ros_python()), '-m', 'tests.bench.steps', *sys.argv[1:]])
    if not isolated():
        reexec_isolated(sys.argv[1:], module='tests.bench.steps')
    sizes = [int(s) for s in args.sizes.split(',')]
    table: dict[str, list[float]] = {}
    for size in sizes:
        # each size in a process of its own would be cleaner; one context, re-made, is enough here
        named, close = steps(size)
        for name, fn in named:
            table.setdefault(name, []).append(best_us(fn, args.windows))
        close()
    with open('/proc/loadavg') as f:
        load = f.read().split()[0]
    width = max(map(len, table))
    print(f'{"step (µs, fastest window)":{width}}' + ''.join(f'{s:>10,}' for s in sizes) + f'   load {load}')
    for name, figures in table.items():
        print(f'{name:{width}}' + ''.join(f'{v:10.2f}' for v in figures))
    print(f'{"sum":{width}}' + ''.join(f'{sum(v[i] for v in table.values()):10.2f}' for i in range(len(sizes))))


if __name__ == '__main__':
    main()
