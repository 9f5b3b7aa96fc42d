# --- rosgate runtime: the same API the IDE's JavaScript runtime offers, over roslibpy ---
import argparse
import atexit
import json
import math
import os
import queue
import random
import re
import signal
import sys
import threading
import time
import traceback

try:
    import roslibpy
except ImportError:   # said when a program starts the runtime (check_roslibpy)
    roslibpy = None

# In the IDE page (Pyodide, ide/js/run/pyrun.js) the program has one thread: roslibpy is the page's
# (ide/runtime/browser/roslibpy.py), waits deliver the messages, handlers run while the program waits.
BROWSER = sys.platform == "emscripten"
if BROWSER:
    import rosgate_browser as _page
    from rosgate_browser import Condition, Event
else:
    Condition, Event = threading.Condition, threading.Event

GAIN = 6.0  # proportional gain of move/turn near the goal (1/s)
# A closed loop stops on the pose it last saw, and its last command runs on for the round trip
# (most of a second on a loaded machine: 0.2 m or 10 degrees). Once the robot has come to rest
# the loop looks again and takes it back, up to PASSES times, until it is within REST_REACH m or
# REST_HEADING rad of its goal (as the IDE's JavaScript runtime does).
PASSES = 3
REST_REACH = 0.02
REST_HEADING = 0.01
SETTLE_SERVICE = "/rosapi/get_time"  # the round trip at the end of the program (Runtime.settle)


class StopProgram(Exception):
    """Raised inside the program when it has to end (Stop, Ctrl-C or an error)."""


class RosError(Exception):
    pass


def fmt(v):
    """Formats a value for log() the same way the IDE does."""
    return v if isinstance(v, str) else _repr(v)


def _repr(v):
    if v is None:
        return "null"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        if v.is_integer() and abs(v) < 1e21:
            return str(int(v))
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_repr(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(json.dumps(str(k), ensure_ascii=False) + ": " + _repr(x)
                               for k, x in v.items()) + "}"
    return str(v)


def field(obj, path):
    """field({'pose': {'x': 1}}, 'pose.x') -> 1; numeric parts index lists."""
    v = obj
    for part in [p for p in str(path).split(".") if p]:
        if isinstance(v, (list, tuple)) and part.lstrip("-").isdigit() and -len(v) <= int(part) < len(v):
            v = v[int(part)]
        elif isinstance(v, dict) and part in v:
            v = v[part]
        else:
            raise RosError("no field '%s' of '%s' in message" % (part, path))
    return v


def pick(msg, selector, index=0):
    """One value out of a message: a field path, or 'min:PATH', 'max:PATH', 'mean:PATH' over the
    finite numbers of a list field (NaN and inf arrive as None), or 'item:PATH' (item `index`,
    from 0; negative counts from the end). min of nothing is inf, max -inf, mean nan."""
    m = re.match(r"^(min|max|mean|item):(.+)$", str(selector), re.S)
    if not m:
        return field(msg, selector)
    how, path = m.groups()
    items = field(msg, path)
    if not isinstance(items, (list, tuple)):
        raise RosError("'%s' is not a list" % path)
    if how == "item":
        try:
            i = float(index)
        except (TypeError, ValueError):
            i = math.nan
        if not (math.isfinite(i) and -len(items) <= int(i) < len(items)):
            raise RosError("no item %s in '%s' (it has %d)" % (fmt(index), path, len(items)))
        return items[int(i)]
    n, acc = 0, {"min": math.inf, "max": -math.inf, "mean": 0.0}[how]
    for v in items:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            continue
        n += 1
        if how == "min":
            acc = v if v < acc else acc
        elif how == "max":
            acc = v if v > acc else acc
        else:
            acc += v
    if how == "mean":
        return acc / n if n else math.nan
    return acc


def yaw(q):
    """Heading in radians from a geometry_msgs/Quaternion."""
    q = q or {}
    x, y, z, w = (q.get(k, d) for k, d in (("x", 0), ("y", 0), ("z", 0), ("w", 1)))
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def angle_diff(a, b):
    """Smallest a - b, wrapped into (-pi, pi] in closed form (a loop of 2*pi steps never ends for
    1e20); nan when either angle is not finite (an infinite angle has no direction), as in the IDE."""
    d = float(a) - float(b)
    if not math.isfinite(d):
        return math.nan
    d = math.remainder(d, 2 * math.pi)
    return math.pi if d <= -math.pi else d


def range_at(scan, degrees=0, window=20):
    """Nearest valid range within +-window/2 degrees of `degrees` (0 ahead, 90 left)."""
    centre = math.radians(float(degrees))
    half = math.radians(abs(float(window))) / 2
    best = math.inf
    for i, r in enumerate(scan.get("ranges") or []):
        if r is None or not math.isfinite(r) or r < scan["range_min"] or r > scan["range_max"]:
            continue
        a = scan["angle_min"] + i * scan["angle_increment"]
        if abs(angle_diff(a, centre)) <= half and r < best:
            best = r
    return best


def is_velocity_type(t):
    return t.split("/")[0] == "geometry_msgs" and t.split("/")[-1] in ("Twist", "TwistStamped")


def _twist(t, linear, angular):
    tw = {"linear": {"x": linear, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": angular}}
    return {"header": {"frame_id": ""}, "twist": tw} if t.endswith("TwistStamped") else tw


def zero_velocity(t):
    return _twist(t, 0.0, 0.0)


def norm_namespace(text):
    """A robot namespace as typed ('s07', '/s07/') -> '/s07', or '' for none."""
    parts = [p.strip() for p in str(text or "").split("/") if p.strip()]
    return "/" + "/".join(parts) if parts else ""


def with_namespace(ns, name):
    """A robot block's name in a namespace: ('/s07', '/turtle1/cmd_vel') -> '/s07/turtle1/cmd_vel';
    a relative name is in the namespace too, and under '/' without one: ('', 'odom') -> '/odom'."""
    name = str(name)
    return norm_namespace(ns) + ("" if name.startswith("/") else "/") + name


def pose_of(msg, t=""):
    if "turtlesim" in t or "theta" in msg:
        return msg["x"], msg["y"], msg["theta"]
    p = msg
    if "pose" in p and "pose" in p["pose"]:
        p = p["pose"]["pose"]
    elif "pose" in p:
        p = p["pose"]
    return p["position"]["x"], p["position"]["y"], yaw(p["orientation"])


class _Sub:
    def __init__(self, topic):
        self.topic = topic
        self.latest = None
        self.cond = Condition()
        self.handlers = []


ROSLIBPY_TESTED = "roslibpy>=2.1,<2.2"


def check_roslibpy():
    """roslibpy drops rosbridge status ops (its table of handlers maps "status" to None), and a
    refused publish has to end the program: the runtime puts its own handler in that table,
    roslibpy's private RosBridgeProtocol._message_handlers. If a roslibpy release renames it,
    refused publishes would silently stop ending programs; the program stops at start instead."""
    if roslibpy is None:
        raise RuntimeError("this program needs roslibpy: pip install '%s'" % ROSLIBPY_TESTED)
    proto = roslibpy.comm.RosBridgeProtocol()
    handlers = getattr(proto, "_message_handlers", None)
    if not isinstance(handlers, dict) or "status" not in handlers:
        raise RuntimeError(
            "this program's runtime needs roslibpy's RosBridgeProtocol._message_handlers table (with a "
            "'status' entry) to end the program when the gateway refuses a publish; roslibpy %s has none. "
            "Install the tested roslibpy: pip install '%s'" % (getattr(roslibpy, "__version__", "?"), ROSLIBPY_TESTED))


class Runtime:
    def __init__(self, url, namespace=""):
        check_roslibpy()
        self.namespace = norm_namespace(namespace)
        self.ros = roslibpy.Ros(url)
        self.ros.run(timeout=10)
        self._program_state()
        self._topics = {}
        self._actions = {}
        self._settled = Event()
        self.ros.factory.on_ready(self._take_status)

    def _program_state(self):
        """What the program control (sleep, latest, on_message, drive ...) keeps."""
        self.stopped = Event()
        self.error = None
        self.t0 = time.monotonic()
        self.handlers = 0
        self._lock = threading.Lock()
        self._subs = {}
        self._velocity = {}
        self._goals = {}

    def ns(self, name):
        """A robot block's name in the robot namespace (--ns)."""
        return with_namespace(self.namespace, name)

    def _take_status(self, proto):
        # roslibpy drops rosbridge status ops; a refused publish has to end the program
        # (check_roslibpy made sure at start that this table is there)
        proto._message_handlers["status"] = self._on_status
        # roslibpy has no action server: goals for the program's served actions (serve_action) go to
        # its listeners by action name, as roslibpy does with service calls; a cancel is not honoured
        # (the goal runs to its result)
        proto._message_handlers["send_action_goal"] = lambda m: self.ros.factory.emit(m["action"], m)
        proto._message_handlers["cancel_action_goal"] = lambda m: None

    def _on_status(self, message):
        # a status error about a publish or advertise of one of the program's topics ends it
        # (roslibpy's ids are "publish:/topic:N"; an older gateway names the topic in the text)
        op_id = str(message.get("id") or "")
        if op_id.startswith("call_service:%s:" % SETTLE_SERVICE):
            self._settled.set()
        if message.get("level") != "error":
            return
        text = str(message.get("msg", "")).replace(" (id %s)" % op_id, "") if op_id else str(message.get("msg", ""))
        mine = re.match(r"(?:publish|advertise):(.+):\d+$", op_id)
        refused = re.match(r"publish: ([^:\s]+):", text)
        topic = mine.group(1) if mine else refused.group(1) if refused and not op_id else None
        if topic in self._topics:
            self.fail(RosError(text))

    def _check(self):
        if self.stopped.is_set():
            raise StopProgram()

    def _wait(self, event, timeout, what):
        end = None if not timeout else time.monotonic() + timeout
        while not event.wait(0.05):
            self._check()
            if end is not None and time.monotonic() > end:
                raise RosError("%s: no answer within %g s" % (what, timeout))
        self._check()

    def fail(self, exc):
        """Ends the program because of an error raised outside the main thread."""
        if not self.stopped.is_set():
            self.error = exc
            if not BROWSER:   # the page reports it with its traceback, at the program's line
                print("error: %s" % exc, file=sys.stderr, flush=True)
            self.stopped.set()

    def _handled(self, handler, value):
        """Run a handler on a worker thread; False once the program stops or the handler fails."""
        try:
            handler(value)
            return True
        except StopProgram:
            return False
        except Exception as e:
            if not BROWSER:
                traceback.print_exc()
            self.fail(e)
            return False

    # ---- program control
    def elapsed(self):
        return time.monotonic() - self.t0

    def sleep(self, seconds):
        if self.stopped.wait(max(0.0, float(seconds or 0))):
            raise StopProgram()

    def log(self, value):
        print(fmt(value), flush=True)

    # ---- topics
    def _topic(self, topic, t):
        with self._lock:
            tp = self._topics.get(topic)
            if tp is None:
                tp = self._topics[topic] = roslibpy.Topic(self.ros, topic, t)
            return tp

    def publish(self, topic, t, msg):
        self._check()
        if is_velocity_type(t):
            self._velocity[topic] = t
        self._topic(topic, t).publish(roslibpy.Message(msg))

    def _subscribe(self, topic, t):
        with self._lock:
            sub = self._subs.get(topic)
            if sub is not None:
                return sub
            sub = self._subs[topic] = _Sub(topic)
        self._listen(topic, t, sub)
        return sub

    def _listen(self, topic, t, sub):
        roslibpy.Topic(self.ros, topic, t).subscribe(lambda msg: self._deliver(sub, msg))

    def _deliver(self, sub, msg):
        """A message to its waiters (latest, wait_for_message) and its handlers (on_message)."""
        if self.stopped.is_set():
            return
        with sub.cond:
            sub.latest = msg
            sub.cond.notify_all()
        for h in list(sub.handlers):
            h(msg)

    def on_message(self, topic, t, handler):
        """Runs handler(msg) in its own thread; while it is busy only the newest message waits."""
        sub = self._subscribe(topic, t)
        slot = {"msg": None, "has": False}
        self.handlers += 1
        if BROWSER:
            sub.handlers.append(self._serial(handler, slot))
            return
        ready = threading.Condition()

        def worker():
            while not self.stopped.is_set():
                with ready:
                    while not slot["has"] and not self.stopped.is_set():
                        ready.wait(0.1)
                    if self.stopped.is_set():
                        return
                    msg, slot["has"] = slot["msg"], False
                if not self._handled(handler, msg):
                    return

        def offer(msg):
            with ready:
                slot["msg"], slot["has"] = msg, True
                ready.notify()

        threading.Thread(target=worker, daemon=True).start()
        sub.handlers.append(offer)

    def _serial(self, handler, slot, keep_all=False):
        """In the browser: handler(value) runs where the message is delivered, one at a time; a
        value that comes while it runs (it waits in turn) waits for it: only the newest, or all
        of them in order (keep_all), as the worker threads do in a script."""
        slot.setdefault("queue", [])
        slot["busy"] = False

        def offer(value):
            if slot["busy"]:
                slot["queue"][:] = slot["queue"] + [value] if keep_all else [value]
                return
            slot["busy"] = True
            try:
                while not self.stopped.is_set() and self._handled(handler, value) and slot["queue"]:
                    value = slot["queue"].pop(0)
            finally:
                slot["busy"] = False
        return offer

    def wait_for_message(self, topic, t, timeout=0):
        sub = self._subscribe(topic, t)
        end = None if not timeout else time.monotonic() + float(timeout)
        with sub.cond:
            before = sub.latest
            while sub.latest is before:
                self._check()
                if end is not None and time.monotonic() > end:
                    raise RosError("no message on %s within %g s" % (topic, float(timeout)))
                sub.cond.wait(0.05)
            return sub.latest

    def latest(self, topic, t, path=""):
        sub = self._subscribe(topic, t)
        msg = sub.latest
        if msg is None:
            msg = self.wait_for_message(topic, t, 10)
        return field(msg, path) if path else msg

    # ---- services and actions
    def call_service(self, service, t, args=None, timeout=0):
        self._check()
        done = Event()
        out = {}

        def ok(values):
            out["values"] = dict(values)
            done.set()

        def err(values):
            out["error"] = values
            done.set()

        roslibpy.Service(self.ros, service, t).call(roslibpy.ServiceRequest(args or {}), ok, err)
        self._wait(done, float(timeout) if timeout else 30.0, "service " + service)
        if "error" in out:
            raise RosError("service %s failed: %s" % (service, out["error"]))
        return out["values"]

    def send_goal(self, action, t, goal=None, on_feedback=None):
        """Sends a goal and waits for its result; on_feedback runs, in order, in a worker thread
        and has handled every feedback before the result is returned."""
        self._check()
        with self._lock:
            client = self._actions.get(action)
            if client is None:
                client = self._actions[action] = roslibpy.ActionClient(self.ros, action, t)
        done = Event()
        out = {}
        feedbacks = queue.Queue()

        def worker():
            while True:
                values = feedbacks.get()
                if values is None or self.stopped.is_set():
                    return
                if not self._handled(on_feedback, values):
                    return

        thread = serial = None
        if on_feedback is not None and BROWSER:
            serial = self._serial(on_feedback, {}, keep_all=True)
        elif on_feedback is not None:
            thread = threading.Thread(target=worker, daemon=True)
            thread.start()

        def feedback(values):
            if serial is not None:
                serial(dict(values))
            elif thread is not None:
                feedbacks.put(dict(values))

        def result(res):
            out["result"] = res
            feedbacks.put(None)
            done.set()

        def error(res):
            out["error"] = res
            feedbacks.put(None)
            done.set()

        goal_id = client.send_goal(dict(goal or {}), result, feedback, error)
        self._goals[goal_id] = client
        try:
            self._wait(done, 0, "action " + action)
        finally:
            self._goals.pop(goal_id, None)
        res = out.get("result") or out.get("error") or {}
        status = int(getattr(res.get("status"), "value", res.get("status") or 0))
        if "error" in out or status != 4:
            what = {5: "was canceled", 6: "was aborted"}.get(status, "ended with status %s" % status)
            raise RosError("action %s %s" % (action, what))
        while thread is not None and thread.is_alive():
            thread.join(0.05)
            self._check()
        return dict(res.get("values") or {})

    # ---- "every N s"
    def every(self, seconds, handler):
        """handler() every `seconds` in a thread of its own (a tick that comes while it still runs is
        skipped), until the program stops. In the page: where the program waits, at its time."""
        period = max(0.01, float(seconds or 0))
        self.handlers += 1
        if BROWSER:
            busy = []

            def tick():
                if self.stopped.is_set():
                    return
                _page.call_later(period, tick)
                if busy:
                    return
                busy.append(True)
                try:
                    self._handled(lambda _: handler(), None)
                finally:
                    busy.clear()
            _page.call_later(period, tick)
            return

        def worker():
            due = time.monotonic() + period
            while not self.stopped.wait(max(0.0, due - time.monotonic())):
                if not self._handled(lambda _: handler(), None):
                    return
                due = max(due + period, time.monotonic())
        threading.Thread(target=worker, daemon=True).start()

    # ---- servers: services and actions the program serves through the gateway
    def _served(self, handler, *args):
        """(handler's answer, True), or (None, False) when it failed (the program ends) or stopped."""
        out = {}
        ok = self._handled(lambda _: out.setdefault("answer", handler(*args)), None)
        return out.get("answer"), ok

    def _serve(self, op, name, t, answer):
        """Advertises; each request (a service call, a goal) is answered by answer(message) in a
        thread of its own, so a slow one holds up neither the connection nor the others (in the
        page: where the program waits, when the request comes)."""
        self._check()
        self.handlers += 1
        if BROWSER:
            self.ros.on(name, lambda m: self.stopped.is_set() or answer(m))
        else:
            self.ros.on(name, lambda m: self.stopped.is_set() or threading.Thread(target=answer, args=(m,), daemon=True).start())
        self.ros.send_on_ready(roslibpy.Message({"op": op, "type": t, op.split("_")[1]: name}))

    def serve_service(self, service, t, handler):
        def answer(m):
            values, ok = self._served(handler, dict(m.get("args") or {}))
            self.ros.send_on_ready(roslibpy.Message({"op": "service_response", "service": service, "id": m.get("id"),
                                                     "values": (values or {}) if ok else "the program failed", "result": ok}))
        self._serve("advertise_service", service, t, answer)

    def serve_action(self, action, t, handler):
        def answer(m):
            values, ok = self._served(handler, dict(m.get("args") or {}), {"action": action, "id": m.get("id")})
            self.ros.send_on_ready(roslibpy.Message({"op": "action_result", "action": action, "id": m.get("id"),
                                                     "values": (values or {}) if ok else {}, "status": 4 if ok else 6, "result": ok}))
        self._serve("advertise_action", action, t, answer)

    def action_feedback(self, goal_handle, values):
        if goal_handle is None:
            raise RosError("'send feedback' works inside 'serve action' only")
        self._check()
        self.ros.send_on_ready(roslibpy.Message({"op": "action_feedback", "action": goal_handle["action"],
                                                 "id": goal_handle["id"], "values": values or {}}))

    def cancel(self, action=None):
        for goal_id, client in list(self._goals.items()):
            if action is None or client.name == action:
                client.cancel_goal(goal_id)

    def settle(self, timeout=2.0):
        """Waits until the gateway has answered every op the program sent: a publish has no reply,
        so an error about the program's last publish could come after the end and be lost. The
        gateway answers in order, so the reply to one more call (a cheap rosapi one, whatever its
        result) comes after any status about the ops before it. Bounded: a server without rosapi
        may never answer."""
        if not self._topics or self.stopped.is_set():
            return
        self._settled.clear()
        roslibpy.Service(self.ros, SETTLE_SERVICE, "rosapi/srv/GetTime").call(
            roslibpy.ServiceRequest({}), lambda _: self._settled.set(), lambda _: self._settled.set())
        self._settled.wait(timeout)

    # ---- robot helpers
    def stop_robot(self):
        for topic, t in list(self._velocity.items()):
            self._topic(topic, t).publish(roslibpy.Message(zero_velocity(t)))

    def drive(self, topic, t, msg, seconds):
        end = time.monotonic() + max(0.0, float(seconds or 0))
        try:
            while time.monotonic() < end:
                self.publish(topic, t, msg)
                self.sleep(min(0.1, max(0.0, end - time.monotonic())))
        finally:
            if not self.stopped.is_set():
                self.publish(topic, t, zero_velocity(t))

    def _rested(self, spec):
        """The pose once the robot has come to rest after a loop's zero: two poses in a row alike,
        within a second (a robot whose odometry never rests: its newest; one that publishes no
        more: its last)."""
        t = spec["pose_type"]

        def pose():
            try:
                return pose_of(self.wait_for_message(spec["pose"], t, 2), t)
            except RosError:
                return pose_of(self.latest(spec["pose"], t), t)
        end = time.monotonic() + 1.0
        prev = pose()
        while time.monotonic() < end:
            p = pose()
            if abs(p[0] - prev[0]) < 1e-3 and abs(p[1] - prev[1]) < 1e-3 and abs(angle_diff(p[2], prev[2])) < 1e-3:
                return p
            prev = p
        return prev

    def move(self, spec, distance, speed=1.0):
        distance = float(distance or 0)
        t = spec.get("type", "geometry_msgs/msg/Twist")
        x0, y0, _ = pose_of(self.latest(spec["pose"], spec["pose_type"]), spec["pose_type"])
        sign = math.copysign(1.0, distance)

        def left(pose):
            return abs(distance) - math.hypot(pose[0] - x0, pose[1] - y0)
        try:
            for _ in range(PASSES):
                way = 0.0   # a pass drives one way, to the goal or past it (no hunting on a late pose)
                while True:
                    remaining = left(pose_of(self.latest(spec["pose"], spec["pose_type"]), spec["pose_type"]))
                    way = way or (math.copysign(1.0, remaining) if remaining else 0.0)
                    if way * remaining <= 0.01:
                        break
                    v = max(0.1, min(float(speed), GAIN * abs(remaining)))
                    self.publish(spec["cmd"], t, _twist(t, sign * way * v, 0.0))
                    self.sleep(0.02)
                self.publish(spec["cmd"], t, zero_velocity(t))
                if abs(left(self._rested(spec))) <= REST_REACH:
                    break
        finally:
            if not self.stopped.is_set():
                self.publish(spec["cmd"], t, zero_velocity(t))

    def turn(self, spec, degrees, speed=90.0):
        target = math.radians(float(degrees or 0))
        rate = math.radians(float(speed))
        t = spec.get("type", "geometry_msgs/msg/Twist")
        state = {"last": pose_of(self.latest(spec["pose"], spec["pose_type"]), spec["pose_type"])[2], "turned": 0.0}

        def seen(th):
            state["turned"] += angle_diff(th, state["last"])
            state["last"] = th
            return target - state["turned"]
        try:
            for _ in range(PASSES):
                way = 0.0
                while True:
                    remaining = seen(pose_of(self.latest(spec["pose"], spec["pose_type"]), spec["pose_type"])[2])
                    way = way or (math.copysign(1.0, remaining) if remaining else 0.0)
                    if way * remaining <= 0.005:
                        break
                    w = max(0.1, min(rate, GAIN * abs(remaining)))
                    self.publish(spec["cmd"], t, _twist(t, 0.0, way * w))
                    self.sleep(0.02)
                self.publish(spec["cmd"], t, zero_velocity(t))
                if abs(seen(self._rested(spec)[2])) <= REST_HEADING:
                    break
        finally:
            if not self.stopped.is_set():
                self.publish(spec["cmd"], t, zero_velocity(t))

    def shutdown(self, timeout=5.0):
        """Zero velocity, goals cancelled, the connection closed: on a thread of its own, for at
        most ``timeout`` s. A Ctrl-C that landed inside the connection's own code can leave it
        unable to send; the program still ends, and the gateway stops the robot when its
        connection closes. True when all of it was done."""
        self.stopped.set()

        def close():
            try:
                self.stop_robot()
                self.cancel()
                self.ros.close()
            except Exception:
                pass
            try:
                self.ros.terminate()
            except Exception:
                pass
        if BROWSER:
            close()
            return True
        closing = threading.Thread(target=close, name="rosgate-shutdown", daemon=True)
        closing.start()
        closing.join(timeout)
        return not closing.is_alive()


class _FirstUse:
    """``rt`` until the runtime runs: a program of plain top-level lines (no main(), no run())
    starts it at its first rt.* call, with the same --url and --ns as run() takes; the end of
    the program then ends it as run() does (message handlers kept until Ctrl-C or Stop)."""

    def __getattr__(self, name):
        return getattr(_start_runtime(), name)

    def __repr__(self):
        return "<the rosgate runtime, started at its first use>"


rt = _FirstUse()
_ending = {"done": False}


def _arguments(namespace):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--url", default=os.environ.get("ROSBRIDGE_URL", "ws://localhost:9090/"),
                        help="rosbridge websocket URL (default: $ROSBRIDGE_URL or ws://localhost:9090/)")
    parser.add_argument("--ns", default=os.environ.get("ROSGATE_NS", namespace),
                        help="robot namespace of the robot blocks, e.g. /s07 (default: $ROSGATE_NS or %r)" % namespace)
    return parser.parse_known_args()[0]


def _start_runtime(namespace=""):
    """The program's runtime, connected at the first call (run() calls it; so does the first rt.*
    of a program with no main())."""
    global rt
    if isinstance(rt, Runtime):
        return rt
    args = _arguments(namespace)
    # Ctrl-C (and a run's Stop, a SIGINT) ends the program even when it was started with SIGINT
    # ignored, as a background job of a shell is: Python then leaves it ignored
    if not BROWSER:   # in the page, Stop ends the worker
        signal.signal(signal.SIGINT, signal.default_int_handler)
        signal.signal(signal.SIGTERM, lambda *_: (_ for _ in ()).throw(KeyboardInterrupt()))
    rt = Runtime(args.url, args.ns)
    if BROWSER:
        _page.at_end(_end_of_lines)
    else:
        atexit.register(_end_of_lines)
    return rt


def _end(main=None):
    """Runs main() (when given), keeps message handlers alive until Ctrl-C, stops the robot; the
    exit code."""
    _ending["done"] = True
    code = 0
    try:
        if main is not None:
            main()
        rt.settle()
        while rt.handlers and not rt.stopped.wait(0.2):
            pass
        if rt.error is not None:
            code = 1
    except (KeyboardInterrupt, StopProgram):
        code = 1 if rt.error is not None else 0
    except Exception:
        if BROWSER:   # the page shows it at the program's line (after the shutdown below)
            raise
        traceback.print_exc()
        code = 1
    finally:
        if not rt.shutdown():
            print("the connection did not close within 5 s: ending anyway (the gateway stops the robot "
                  "when the connection goes)", file=sys.stderr)
    sys.stdout.flush()
    sys.stderr.flush()
    return code


def _end_of_lines():
    """The end of a program of top-level lines (the runtime started at its first rt.* call)."""
    if _ending["done"] or not isinstance(rt, Runtime):
        return
    code = _end()
    if BROWSER:
        if rt.error is not None:
            raise rt.error
        return
    os._exit(code)


def run(main, namespace=""):
    """Connects, runs main(), keeps message handlers alive until Ctrl-C, stops the robot."""
    runtime = _start_runtime(namespace)
    # a program that imports the runtime (from rosgate_runtime import *) bound rt before it ran:
    # its main() sees this one
    main.__globals__["rt"] = runtime
    code = _end(main)
    if BROWSER:
        if rt.error is not None:
            raise rt.error
        raise SystemExit(code)
    os._exit(code)   # not sys.exit: a thread the connection left behind cannot keep the program alive
# --- end of the rosgate runtime ---
