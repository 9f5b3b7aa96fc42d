"""The Python worker's side of the IDE page (ide/js/run/pyworker.js, ide/js/run/pyrun.js).

The program has one thread. Whatever blocks (``time.sleep``, ``Event.wait``, a blocking service
call, ``run_forever``) waits in ``pump``: the page writes the gateway's messages for the program
into a shared buffer and the worker sleeps on it with Atomics.wait, so a message ends the wait
at once and its callbacks run there, in the program's thread. A program that never blocks still
gets its messages every ``PUMP_EVERY`` lines it runs.
"""

import builtins
import heapq
import itertools
import json
import linecache
import os
import sys
import time
import traceback

import _rosgate_js as _js
import rosgate_interfaces

PROGRAM = "<program>"       # the file name of the student's code in tracebacks
PUMP_EVERY = 2000           # lines run between looks at the mailbox in a program that does not block
TOOL = 3                    # the sys.monitoring tool id of the running-line tracker

_protocols = []             # the program's open roslibpy connections (RosBridgeProtocol)
_timers = []                # (when, n, callback) of call_later
_order = itertools.count()
_ids = itertools.count(1)
_sleep = time.sleep
_ends = []                  # what runs when the program's lines have run (at_end)


def next_id():
    """The N of an op id: above the run's base, so the page tells the program's replies apart."""
    return next(_ids)


def at_end(hook):
    """hook() runs when the program's top-level lines have run (the runtime's end of a program
    with no main(): its handlers kept until Stop, the robot stopped)."""
    _ends.append(hook)


def attach(proto):
    _protocols.append(proto)


def detach(proto):
    if proto in _protocols:
        _protocols.remove(proto)


def send(payload):
    _js.send(payload)


def close():
    """A roslibpy connection closed: the page ends what the program started (zero velocity,
    goals cancelled, subscriptions and advertisements ended), as the gateway does when a
    script's connection closes."""
    _js.close()


def call_later(delay, callback):
    heapq.heappush(_timers, (time.monotonic() + max(0.0, float(delay)), next(_order), callback))


class _Replies:
    """The gateway's answers to the page's own requests (request()), by op id."""

    def __init__(self):
        self.waiting = {}          # op id -> the answer, or None while it has not come

    def on_message(self, message):
        op_id = message.get("id")
        if op_id in self.waiting and message.get("op") in ("service_response", "action_result", "status"):
            if message.get("op") != "status" or message.get("level") == "error":
                self.waiting[op_id] = message


_replies = _Replies()
_protocols.append(_replies)


def request(message, timeout=10.0):
    """Sends an op (with its id) and waits for the gateway's answer to it: its service_response
    or action_result, or a status error naming it. TimeoutError after ``timeout`` s."""
    op_id = message["id"]
    _replies.waiting[op_id] = None
    send(json.dumps(message))
    end = time.monotonic() + timeout
    try:
        while _replies.waiting[op_id] is None:
            left = end - time.monotonic()
            if left <= 0:
                raise TimeoutError("no answer to %s within %g s" % (op_id, timeout))
            pump(left)
        return _replies.waiting[op_id]
    finally:
        _replies.waiting.pop(op_id, None)


def rosapi(name, args=None, timeout=60.0):
    """The values of a /rosapi/NAME call; LookupError with the gateway's words when it fails."""
    service = "/rosapi/" + name
    answer = request({"op": "call_service", "id": "call_service:%s:%d" % (service, next_id()),
                      "service": service, "args": args or {}}, timeout)
    if answer.get("op") == "status" or answer.get("result") is False:
        raise LookupError(answer.get("values") if answer.get("op") != "status" else answer.get("msg"))
    return answer.get("values") or {}


def _details(service, type_):
    return rosapi(service, {"type": type_})["typedefs"]


def _packages():
    """The ROS packages whose types the gateway knows (None when it cannot say: a rosbridge
    server without rosapi's ``interfaces``)."""
    try:
        names = rosapi("interfaces").get("interfaces") or []
    except LookupError:
        return None
    return {n.split("/")[0] for n in names}


def pump(timeout):
    """Waits up to ``timeout`` s (None: until something comes) for the gateway's messages, hands
    each to the program's connections, runs due timers. True when something came."""
    ms = float("inf") if timeout is None else max(0.0, float(timeout)) * 1000
    if _timers:
        ms = min(ms, max(0.0, (_timers[0][0] - time.monotonic()) * 1000))
    text = _js.take(ms)
    for line in text.splitlines():
        if line:
            message = json.loads(line)
            for proto in list(_protocols):
                proto.on_message(message)
    now = time.monotonic()
    while _timers and _timers[0][0] <= now:
        heapq.heappop(_timers)[2]()
    return bool(text)


def sleep(seconds):
    """time.sleep that delivers the program's messages while it waits."""
    seconds = float(seconds)
    if seconds < 0:
        raise ValueError("sleep length must be non-negative")
    end = time.monotonic() + seconds
    while True:
        left = end - time.monotonic()
        if left <= 0:
            return
        pump(left)


class Event:
    """threading.Event for the one thread: waiting delivers messages, whose callbacks set it."""

    def __init__(self):
        self._flag = False

    def is_set(self):
        return self._flag

    def set(self):
        self._flag = True

    def clear(self):
        self._flag = False

    def wait(self, timeout=None):
        end = None if timeout is None else time.monotonic() + float(timeout)
        while not self._flag:
            left = None if end is None else end - time.monotonic()
            if left is not None and left <= 0:
                break
            pump(left)
        return self._flag


class Condition:
    """threading.Condition for the one thread: wait() delivers messages until one comes or the
    time is up (the caller looks again, as it does after a notify)."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def wait(self, timeout=None):
        return pump(timeout)

    def notify(self, n=1):
        pass

    def notify_all(self):
        pass


class _Lines:
    """Tells the page the running line of the program (sys.monitoring's LINE events, turned off
    for code that is not the program's), and delivers messages every PUMP_EVERY lines."""

    def __init__(self):
        self.last = 0
        self.count = 0

    def __call__(self, code, line):
        if code.co_filename != PROGRAM:
            return sys.monitoring.DISABLE
        if line != self.last:
            self.last = line
            _js.line(line)
        self.count += 1
        if self.count >= PUMP_EVERY:
            self.count = 0
            pump(0)
        return None

    def start(self):
        mon = sys.monitoring
        mon.use_tool_id(TOOL, "rosgate")
        mon.register_callback(TOOL, mon.events.LINE, self)
        mon.set_events(TOOL, mon.events.LINE)

    @staticmethod
    def stop():
        mon = sys.monitoring
        mon.set_events(TOOL, 0)
        mon.register_callback(TOOL, mon.events.LINE, None)
        mon.free_tool_id(TOOL)


def error_of(exc):
    """{line, message, traceback} of an exception: the program's own frames and line numbers."""
    frames = [f for f in traceback.extract_tb(exc.__traceback__) if f.filename == PROGRAM]
    line = frames[-1].lineno if frames else None
    if isinstance(exc, SyntaxError) and exc.filename == PROGRAM:
        line = exc.lineno
    only = traceback.format_exception_only(type(exc), exc)
    text = "".join((["Traceback (most recent call last):\n"] + traceback.format_list(frames) if frames else []) + only)
    return {"line": line, "message": only[-1].strip(), "traceback": text.rstrip("\n")}


def check(source):
    """Python's own syntax check: [{line, col, message}] (from 1), [] when the program compiles."""
    try:
        compile(source, PROGRAM, "exec", dont_inherit=True)
    except SyntaxError as e:
        return [{"line": e.lineno or 1, "col": e.offset or 1, "message": "%s: %s" % (type(e).__name__, e.msg)}]
    except ValueError as e:   # a NUL byte
        return [{"line": 1, "col": 1, "message": str(e)}]
    return []


def run(source, namespace, base, args=()):
    """Runs the program as __main__; None when it ended, {line, message, traceback} on an error.
    ROS message, service and action modules (``from std_msgs.msg import String``) are made from
    the gateway's definitions when the program imports them (rosgate_interfaces)."""
    global _ids
    _ids = itertools.count(int(base))
    rosgate_interfaces.install(rosgate_interfaces.Interfaces(_details, _packages))
    os.environ["ROSGATE_NS"] = namespace or ""
    sys.argv = ["program.py"] + [str(a) for a in args]
    time.sleep = sleep
    linecache.cache[PROGRAM] = (len(source), None, source.splitlines(True), PROGRAM)
    lines = _Lines()
    lines.start()
    try:
        exec(compile(source, PROGRAM, "exec", dont_inherit=True),
             {"__name__": "__main__", "__file__": PROGRAM, "__builtins__": builtins})
        while _ends:
            _ends.pop(0)()
    except SystemExit as e:
        if e.code not in (None, 0) and not isinstance(e.code, int):
            print(e.code, file=sys.stderr)
    except BaseException as e:   # noqa: BLE001: every error of the program is reported, at its line
        return error_of(e)
    finally:
        lines.stop()
        time.sleep = _sleep
        sys.stdout.flush()
        sys.stderr.flush()
    return None
