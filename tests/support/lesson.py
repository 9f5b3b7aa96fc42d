"""A class through a lesson: the students' and the teacher's tokens, the teacher's independent
client following /rosgate/stations and /rosgate/driver, and a student's IDE on her station."""

from __future__ import annotations

import json
import threading
import time

from tests.support.ide import PATIENCE_MS, IdePage, ex, program
from tests.support.wait import TIMEOUT, wait_for

TWIST = "geometry_msgs/msg/Twist"
POSE = "turtlesim/msg/Pose"
TOKENS = {"teacher": "teacher-token-0001", "ada": "ada-token-0002", "bo": "bo-token-0003",
          "cy": "cy-token-0004", "dee": "dee-token-0005"}



def tokens_file(folder) -> str:
    """A tokens file in ``folder`` giving each of TOKENS its person: the teacher an admin, the rest operators."""
    path = folder / "tokens.toml"
    path.write_text("".join(
        f'[[tokens]]\nname = "{name}"\nrole = "{"admin" if name == "teacher" else "operator"}"\ntoken = "{token}"\n\n'
        for name, token in TOKENS.items()))
    return str(path)

class Teacher:
    """A roslibpy client signed in as the teacher, following /rosgate/stations and /rosgate/driver."""

    def __init__(self, gw):
        import roslibpy
        self.roslibpy = roslibpy
        self.ros = roslibpy.Ros(f"ws://{gw.host}:{gw.port}/?token={TOKENS['teacher']}")
        self.ros.run(timeout=TIMEOUT)
        self.lock = threading.Lock()
        self.stations: list[tuple[float, dict]] = []
        self.drivers: list[dict] = []
        self.messages: dict[str, list[tuple[float, dict]]] = {}
        self.follow("/rosgate/stations", lambda m: self.stations.append((time.monotonic(), json.loads(m["data"]))))
        self.follow("/rosgate/driver", lambda m: self.drivers.append(json.loads(m["data"])))
        wait_for(lambda: self.stations and self.drivers, what="the gateway's announcements")

    def follow(self, topic: str, on, type_: str = "std_msgs/msg/String"):
        def take(m):
            with self.lock:
                on(m)
        self.roslibpy.Topic(self.ros, topic, type_).subscribe(take)

    def watch(self, topic: str, type_: str) -> list:
        box = self.messages.setdefault(topic, [])
        self.follow(topic, lambda m: box.append((time.monotonic(), dict(m))), type_)
        return box

    def owners(self) -> dict:
        with self.lock:
            return {ns: o["name"] for ns, o in self.stations[-1][1]["owners"].items()}

    def owners_since(self, t0: float) -> list[dict]:
        with self.lock:
            return [{ns: o["name"] for ns, o in info["owners"].items()} for t, info in self.stations if t >= t0]

    def driver(self, ns: str):
        with self.lock:
            return (self.drivers[-1]["drivers"].get(ns) or {}).get("name")

    def drove(self, ns: str, which) -> bool:
        """Whether a holder of ns for which which(holder) is true was announced."""
        with self.lock:
            return any(which(d["drivers"][ns]) for d in self.drivers if d["drivers"].get(ns))

    def round_trip(self):
        """Everything sent to the gateway before this has been handled."""
        self.roslibpy.Service(self.ros, "/rosapi/get_time", "rosapi/srv/GetTime").call(
            self.roslibpy.ServiceRequest({}), timeout=TIMEOUT)

    def close(self):
        self.ros.close()


def open_ide(ctx, gw, query: str = "") -> IdePage:
    return IdePage(ctx.new_page(), gw).open(gw.http_url + query)


def on_station(ide: IdePage, ns: str):
    ide.page.wait_for_function("([ns]) => rosgateIde.ns === ns && rosgateIde.robotNs.mine === ns "
                               "&& rosgateIde.lease.state === 'you'", arg=[ns], timeout=PATIENCE_MS)


def console_says(ide: IdePage, pattern: str):
    ide.page.wait_for_function("(p) => new RegExp(p).test(document.querySelector('#console-lines').innerText)",
                               arg=pattern, timeout=PATIENCE_MS)


def move(metres: float = 1.0) -> dict:
    return program(ex.block("turtle_move", id="move", inputs={"TURTLE": ex.text("turtle1"), "DIST": ex.num(metres)}))
