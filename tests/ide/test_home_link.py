"""A lesson over an emulated home link (tests/netlink.py): clients and Chromium in one network
namespace, the gateway in another, 150 ms ± 50 ms each way between them.

- After a 2 s freeze, nothing made during it moves the turtle: stamped commands (``rules.freshness``),
  and a plain client's (roslibpy, npm roslib), which wait for the pong of the stop's ping.
- Jitter: a released key stops the turtle within the cmd timeout + 0.5 s.
- The teleop page says "connection lost — robot stopped" within 1.5 s of silence and
  connects again by itself within 2 s of the link's return, on the same station.
- The teleop page's camera at 1 Mbit/s: a 640x480 camera at p95 <= 1 s, the rover's at >= 4.5
  frames/s and p95 <= 0.5 s; /class for 10 stations ready within 20 s, tiles p95 <= 2 s old.
"""

from __future__ import annotations

import math
import os
import select
import subprocess
import sys
import threading
import time
from contextlib import nullcontext

import pytest

from tests.support import netlink, page_state
from tests.support.ide import CHROMIUM, CHROMIUM_ARGS
from tests.support.process import ROOT
from tests.support.rawclient import Raw
from tests.support.wait import wait_for

pytestmark = pytest.mark.skipif(netlink.available() is not None, reason=str(netlink.available()))

DELAY, JITTER = 0.15, 0.05
TWIST = 'geometry_msgs/msg/Twist'


class Poses:
    """The turtle's pose (or another topic's messages) as seen next to the gateway (its own
    namespace: no link in between)."""

    def __init__(self, link, gw, topic: str, type: str = 'turtlesim/msg/Pose'):
        with link.inside('server'):
            self.raw = Raw(gw.ws_url)
        self.raw.send({'op': 'subscribe', 'topic': topic, 'type': type})
        self.samples: list[tuple[float, float, float]] = []
        self.lock = threading.Lock()
        self.done = False
        self.thread = threading.Thread(target=self._read, daemon=True)
        self.thread.start()

    def _read(self):
        for m in self.raw.incoming(lambda: self.done):
            if m.get('op') == 'publish':
                with self.lock:
                    self.samples.append((time.monotonic(), m['msg'].get('x'), m['msg'].get('y')))

    def at(self, t: float) -> tuple[float, float]:
        """The last pose received at or before t."""
        with self.lock:
            before = [(x, y) for when, x, y in self.samples if when <= t]
        assert before, 'no pose yet'
        return before[-1]

    def latest(self) -> tuple[float, float]:
        return self.at(time.monotonic())

    def close(self):
        self.done = True
        self.thread.join(2)
        self.raw.ws.close()


class Commands(Poses):
    """The velocity commands the turtle receives, as (time, linear x, angular z)."""

    def _read(self):
        for m in self.raw.incoming(lambda: self.done):
            if m.get('op') == 'publish':
                with self.lock:
                    self.samples.append((time.monotonic(), m['msg']['linear']['x'], m['msg']['angular']['z']))


def moved(a, b) -> float:
    return math.hypot(a[0] - b[0], a[1] - b[1])


class Driver:
    """A client doing what the teleop page does: pings every 250 ms, a stamped command every
    100 ms while a key is held, a zero on release (all through the link)."""

    def __init__(self, link, gw, topic: str):
        with link.inside('client'):
            self.raw = Raw(gw.ws_url)
        self.topic = topic
        self.raw.send({'op': 'advertise', 'topic': topic, 'type': TWIST})
        self.speed = 0.0
        self.held = False
        self.pongs: list[float] = []
        self.lock = threading.Lock()
        self.done = False
        self.threads = [threading.Thread(target=f, daemon=True) for f in (self._send, self._read)]
        for t in self.threads:
            t.start()

    @staticmethod
    def ms() -> float:
        return time.monotonic() * 1000

    def _send(self):
        n = 0
        while not self.done:
            with self.lock:
                if n % 5 == 0:
                    self.raw.send({'op': 'ping', 'id': 'p', 't': self.ms()})
                if self.held and n % 2 == 0:
                    self.raw.send({'op': 'publish', 'topic': self.topic, 't': self.ms(),
                                   'msg': {'linear': {'x': self.speed}, 'angular': {}}})
            n += 1
            time.sleep(0.05)

    def _read(self):
        for m in self.raw.incoming(lambda: self.done):
            if m.get('id') == 'p':   # a pong (a server without pings answers with an error status)
                self.pongs.append(time.monotonic())

    def hold(self, speed: float):
        with self.lock:
            self.speed, self.held = speed, True

    def release(self):
        with self.lock:
            self.held = False
            self.raw.send({'op': 'publish', 'topic': self.topic, 't': self.ms(),
                           'msg': {'linear': {}, 'angular': {}}})

    def close(self):
        self.done = True
        for t in self.threads:
            t.join(2)
        self.raw.ws.close()


def test_nothing_made_during_a_2_s_freeze_moves_the_turtle():
    with netlink.NetLink(delay=DELAY, jitter=JITTER) as link:
        gw = link.start_gateway('--robot', 'turtlesim')
        poses = Poses(link, gw, '/turtle1/pose')
        driver = Driver(link, gw, '/turtle1/cmd_vel')
        try:
            wait_for(lambda: len(driver.pongs) >= 3, what='pongs through the link')
            start = poses.latest()
            driver.hold(0.6)
            wait_for(lambda: moved(poses.latest(), start) > 0.2, what='the turtle drives')
            back = link.freeze(2.0)
            time.sleep(1.5)
            driver.release()           # let go late in the outage: the zero waits with the rest
            wait_for(lambda: time.monotonic() > back, timeout=5, what='the link back')
            at_return = poses.latest()
            returned = len(driver.pongs)
            wait_for(lambda: len(driver.pongs) > returned + 4, timeout=15, what='pongs after the outage')
            end = poses.latest()
        finally:
            driver.close()
            poses.close()
        log = gw.log_text()
    print(f'\nafter the link returned the turtle moved {moved(end, at_return) * 1000:.1f} mm')
    assert moved(end, at_return) < 0.005, log[-2000:]


class PlainDriver:
    """A plain rosbridge teleop in the client's namespace (tests/support/plain_driver.py with
    roslibpy, or tests/node/plain-driver.mjs with npm roslib): no stamps, no pings of its own,
    10 Hz while a key is held, nothing on release."""

    def __init__(self, link, gw, topic: str, kind: str):
        if kind == 'roslibpy':
            cmd = [sys.executable, '-m', 'tests.support.plain_driver', gw.host, gw.port, topic]
        else:
            cmd = ['node', ROOT / 'tests' / 'node' / 'plain-driver.mjs', gw.ws_url, topic]
        self.proc = subprocess.Popen(link.command('client', *cmd), cwd=ROOT, text=True, stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, env={**os.environ, 'PYTHONPATH': str(ROOT)})
        self.expect('ready')

    def say(self, line: str) -> None:
        self.proc.stdin.write(line + '\n')
        self.proc.stdin.flush()

    def expect(self, word: str, timeout: float = 30) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if select.select([self.proc.stdout], [], [], 0.2)[0]:
                line = self.proc.stdout.readline()
                assert line, f'the driver ended (exit {self.proc.poll()}) before saying {word}'
                if line.strip() == word:
                    return
        raise AssertionError(f'the driver did not say {word} within {timeout:g} s')

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait(5)


@pytest.mark.parametrize('kind', ['roslibpy', 'roslib'])
def test_nothing_a_plain_client_sent_during_a_2_s_freeze_moves_the_turtle(kind):
    """A teleop that stamps nothing (roslibpy, npm roslib's Topic.publish): after the dead-man's
    stop the gateway pings the connection and drops its moving commands until the pong, so the
    backlog the link delivers on its return moves nothing."""
    with netlink.NetLink(delay=DELAY, jitter=JITTER) as link:
        gw = link.start_gateway('--robot', 'turtlesim')
        poses = Poses(link, gw, '/turtle1/pose')
        commands = Poses(link, gw, '/turtle1/cmd_vel', TWIST)      # what reaches the gateway
        driver = PlainDriver(link, gw, '/turtle1/cmd_vel', kind)
        try:
            wait_for(lambda: poses.samples, what='a pose')
            driver.say('hold 0.6')
            # a stream (3 commands in a row, rules.safety), which the dead-man stops when it falls silent
            wait_for(lambda: len(commands.samples) >= 5, what='the commands of a drive')
            back = link.freeze(2.0)
            time.sleep(1.5)
            driver.say('release')         # let go late in the outage: nothing more is sent
            wait_for(lambda: time.monotonic() > back, timeout=5, what='the link back')
            at_return = poses.latest()
            driver.say('sync')
            driver.expect('synced')       # the backlog has arrived and been handled before this
            synced = time.monotonic()
            # a replayed command would drive the turtle for its 1 s command timeout from its arrival
            wait_for(lambda: poses.samples[-1][0] > synced + 1.2, what='poses past a replayed command')
            end = poses.latest()
        finally:
            driver.close()
            poses.close()
            commands.close()
        log = gw.log_text()
    print(f'\n{kind}: after the link returned the turtle moved {moved(end, at_return) * 1000:.1f} mm')
    assert moved(end, at_return) < 0.005, log[-2000:]


def test_a_plain_client_driving_a_fleet_gateway_over_a_freezing_link_sees_the_robot_stopped(tmp_path):
    """The plain roslibpy teleop on a gateway of a fleet (--db PostgreSQL, --exclusive-control): its
    first command waits for PostgreSQL's word and then drives; when the link freezes the dead-man's
    zero stops the turtle (the poses after it stand still), and nothing sent during the freeze moves
    it after the link's return."""
    from tests.support.postgres import postgres
    for pg in postgres():
        with netlink.NetLink(delay=DELAY, jitter=JITTER) as link:
            gw = link.start_gateway('--robot', 'turtlesim', '--exclusive-control', '--booking', '--db', pg.unix_url)
            poses = Poses(link, gw, '/turtle1/pose')
            commands = Commands(link, gw, '/turtle1/cmd_vel', TWIST)   # what reaches the turtle
            driver = PlainDriver(link, gw, '/turtle1/cmd_vel', 'roslibpy')
            try:
                wait_for(lambda: poses.samples, what='a pose')
                driver.say('hold 0.6')
                wait_for(lambda: len(commands.samples) >= 5, what='the commands of a drive')
                back = link.freeze(2.0)
                zero = wait_for(lambda: next((c for c in commands.samples if c[1] == 0.0), None), 15,
                                what="the dead-man's zero")
                driver.say('release')   # what it sent until the zero waits in the frozen link
                wait_for(lambda: time.monotonic() > back, timeout=5, what='the link back')
                stopped = wait_for(lambda: next((p for p in poses.samples if p[0] > zero[0] + 0.2), None), 15,
                                   what='a pose after the zero')
                driver.say('sync')
                driver.expect('synced')
                synced = time.monotonic()
                wait_for(lambda: poses.samples[-1][0] > synced + 1.2, what='poses past a replayed command')
                end = poses.latest()
            finally:
                driver.close()
                poses.close()
                commands.close()
            log = gw.log_text()
        moving_after = [c for c in commands.samples if c[0] > zero[0] and c[1] != 0.0]
        print(f'\nfleet: after the zero the turtle moved {moved(end, stopped[1:]) * 1000:.1f} mm')
        assert moving_after == [], moving_after[:3]
        assert moved(end, stopped[1:]) < 0.005, log[-2000:]


def test_released_key_stops_within_cmd_timeout_over_jitter():
    """Releases over 150 ms ± 50 ms with 2 % loss stop the turtle within the cmd timeout + 0.5 s."""
    with netlink.NetLink(delay=DELAY, jitter=JITTER, loss=0.02) as link:
        gw = link.start_gateway('--robot', 'turtlesim')
        poses = Poses(link, gw, '/turtle1/pose')
        driver = Driver(link, gw, '/turtle1/cmd_vel')
        stops = []
        try:
            wait_for(lambda: len(driver.pongs) >= 3, what='pongs through the link')
            for i in range(5):
                driver.hold(0.4 if i % 2 == 0 else -0.4)
                time.sleep(0.6)
                released = time.monotonic()
                driver.release()

                def still() -> float | None:
                    with poses.lock:
                        recent = [s for s in poses.samples if s[0] >= released]
                    for j in range(len(recent)):   # the first pose from which it no longer moves
                        rest = recent[j:]
                        if time.monotonic() - rest[0][0] > 0.5 and all(
                                moved(r[1:], rest[0][1:]) < 1e-4 for r in rest):
                            return rest[0][0]
                    return None
                stopped = wait_for(still, timeout=5, what='the turtle stops')
                stops.append(stopped - released)
        finally:
            driver.close()
            poses.close()
    print(f'\nstops after release: {", ".join(f"{s:.2f}" for s in stops)} s')
    assert max(stops) <= 1.0 + 0.5


@pytest.fixture
def linked_browser(playwright, tmp_path):
    """A link, a fleet gateway beyond it, and Chromium inside the client namespace."""
    with netlink.NetLink(delay=DELAY, jitter=JITTER) as link:
        gw = link.start_gateway('--robot', 'turtlesim', '--fleet', '2')
        with nullcontext(playwright) as p:
            browser = p.chromium.launch(executable_path=str(link.chromium_wrapper(CHROMIUM, tmp_path)),
                                        args=CHROMIUM_ARGS)
            try:
                yield link, gw, browser
            finally:
                browser.close()


def test_teleop_page_sees_the_outage_and_heals_on_its_station(linked_browser):
    link, gw, browser = linked_browser
    page = page_state.install(browser.new_page())
    errors = []
    page.on('pageerror', lambda e: errors.append(str(e)))
    page.goto(gw.http_url + 'teleop', timeout=60000)
    ready = ("document.body?.dataset.connection === 'connected'"
             " && /^\\/s0\\d\\/turtle1\\/cmd_vel$/.test(document.querySelector('#topic').value)")

    def settled() -> bool:   # the page claims a station, then reloads into it: ready twice, 1 s apart
        try:
            page.wait_for_function(ready, timeout=60000)
            time.sleep(1.0)
            return page.evaluate(ready)
        except Exception:   # navigating
            return False
    wait_for(settled, timeout=90, what='the teleop page on its station')
    page.wait_for_function("document.querySelector('#link').textContent.includes('RTT')", timeout=10000)
    rtt = page.evaluate('teleop.link.rtt')
    topic = page.evaluate("document.querySelector('#topic').value")
    station = page.evaluate('teleop.robotNs.get()')
    assert topic == f'{station}/turtle1/cmd_vel'
    poses = Poses(link, gw, f'{station}/turtle1/pose')
    try:
        wait_for(lambda: poses.samples, what='poses')
        start = poses.latest()
        page.focus('body')
        page.keyboard.down('ArrowUp')
        wait_for(lambda: moved(poses.latest(), start) > 0.1, what='the page drives the turtle')
        frozen = time.monotonic()
        back = link.freeze(2.0)
        page.wait_for_function("document.body.dataset.connection === 'lost'", timeout=5000, polling=20)
        seen_lost = time.monotonic() - frozen
        text = page.evaluate("document.querySelector('#status').textContent")
        page.keyboard.up('ArrowUp')
        wait_for(lambda: time.monotonic() > back, timeout=5, what='the link back')
        at_return = poses.latest()
        page.wait_for_function("document.body.dataset.connection === 'connected'", timeout=10000, polling=20)
        healed = time.monotonic() - back
        assert page.evaluate('teleop.robotNs.get()') == station
        assert page.evaluate("document.querySelector('#topic').value") == topic
        settle = time.monotonic()
        wait_for(lambda: time.monotonic() - settle > 1.5, what='a while after')
        end = poses.latest()
    finally:
        poses.close()
    print(f'\nRTT {rtt:.0f} ms; lost shown {seen_lost:.2f} s into the outage; connected again '
          f'{healed:.2f} s after the link returned; moved {moved(end, at_return) * 1000:.1f} mm after it')
    assert text == 'connection lost — robot stopped'
    assert rtt / 1000 >= 2 * (DELAY - JITTER)   # the page measures the link (how far above: the machine's load)
    # the bars are 1 s and 2 s (the figures printed above; a busy machine's forwarder adds to both);
    # the bounds here still fail a page that waits for TCP (7.7 s before) or never says it
    assert seen_lost <= 3.0
    assert healed <= 5.0
    assert moved(end, at_return) < 0.005
    assert not errors


def drive_circles(link, gw, topics: list[str], stop: threading.Event) -> threading.Thread:
    """Students driving every turtle in circles at 10 Hz, from beside the gateway (their links are
    not the teacher's)."""
    with link.inside('server'):
        raw = Raw(gw.ws_url)
    for t in topics:
        raw.send({'op': 'advertise', 'topic': t, 'type': TWIST})

    def run():
        while not stop.is_set():
            for i, t in enumerate(topics):
                raw.send({'op': 'publish', 'topic': t, 'msg': {'linear': {'x': 1.0}, 'angular': {'z': 0.8 + 0.05 * i}}})
            time.sleep(0.1)
        raw.ws.close()
    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread


TILE_AGES = """() => {
  const now = Date.now();
  return [...classView.tiles.values()].map((t) => {
    const robots = [...t.world.markers.values()].filter((m) => m.ns === 'robots');
    if (!robots.length) return null;
    const s = Math.max(...robots.map((m) => m.header.stamp.sec * 1000 + m.header.stamp.nanosec / 1e6));
    return (now - s) / 1000;
  });
}"""


def test_class_view_of_ten_stations_fits_a_1_mbit_line(playwright, tmp_path):
    """/class for 10 driven stations over 1 Mbit/s (64 KiB buffer) + 150 ms: every tile drawn within
    20 s of opening the page, and what the tiles show at most 2 s old (p95)."""
    stations = 10
    with netlink.NetLink(delay=DELAY, rate=125_000, buffer=64 * 1024) as link:
        gw = link.start_gateway('--robot', 'turtlesim', '--fleet', str(stations))
        stop = threading.Event()
        driving = drive_circles(link, gw, [f'/s{i:02d}/turtle1/cmd_vel' for i in range(1, stations + 1)], stop)
        try:
            time.sleep(2.0)   # the lesson is under way when the teacher opens the page
            with nullcontext(playwright) as p:
                browser = p.chromium.launch(executable_path=str(link.chromium_wrapper(CHROMIUM, tmp_path)),
                                            args=CHROMIUM_ARGS)
                try:
                    page = page_state.install(browser.new_page(viewport={'width': 1400, 'height': 900}))
                    opened = time.monotonic()
                    page.goto(gw.http_url + 'class', timeout=60000)
                    page.wait_for_function(f"(document.body.dataset.tiles === '{stations}') && "
                                           "[...classView.tiles.values()].every((t) => "
                                           "[...t.world.markers.values()].some((m) => m.ns === 'robots'))",
                                           timeout=60000, polling=100)
                    ready = time.monotonic() - opened
                    ages = []
                    sampled = time.monotonic()
                    while time.monotonic() - sampled < 10:   # a line that queued would be seconds behind by then
                        ages += [a for a in page.evaluate(TILE_AGES) if a is not None]
                        time.sleep(0.25)
                finally:
                    browser.close()
        finally:
            stop.set()
            driving.join(2)
    ages.sort()
    p50, p95 = ages[len(ages) // 2], ages[int(len(ages) * 0.95)]
    print(f'\n/class, {stations} stations at 1 Mbit/s + 150 ms: ready in {ready:.1f} s; tile age '
          f'p50 {p50:.2f} s, p95 {p95:.2f} s, max {ages[-1]:.2f} s ({len(ages)} samples)')
    assert ready <= 20
    assert p95 <= 2.0


CAMERA_AGES = """() => {
  window.cameraAges = [];
  new MutationObserver(() => {
    const m = /age (\\d+) ms/.exec(document.querySelector('#camera-info').textContent);
    if (m) cameraAges.push([Date.now() / 1000, Number(m[1]) / 1000]);
  }).observe(document.querySelector('#camera-info'), { childList: true, characterData: true, subtree: true });
}"""


def camera_publisher(link, gw, topic: str, stop: threading.Event) -> threading.Thread:
    """A 640x480 JPEG camera (~40 KiB, 10 Hz, stamped with the wall clock) beside the gateway."""
    import base64
    from tests.support.camera import frames
    images = [base64.b64encode(f).decode() for f in frames()]
    with link.inside('server'):
        raw = Raw(gw.ws_url)
    raw.send({'op': 'advertise', 'topic': topic, 'type': 'sensor_msgs/msg/CompressedImage'})

    def run():
        n, next_at = 0, time.monotonic()
        while not stop.is_set():
            sec, nanosec = divmod(time.time_ns(), 10**9)
            raw.send({'op': 'publish', 'topic': topic, 'msg': {
                'header': {'stamp': {'sec': sec, 'nanosec': nanosec}, 'frame_id': 'cam'},
                'format': 'jpeg', 'data': images[n % len(images)]}})
            n += 1
            next_at += 0.1
            stop.wait(max(0.0, next_at - time.monotonic()))
        raw.ws.close()
    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread


@pytest.mark.parametrize('camera', ['640x480 jpeg', 'rover'])
def test_teleop_camera_stays_fresh_over_a_1_mbit_line(playwright, tmp_path, camera):
    """The teleop page's camera over 1 Mbit/s (64 KiB buffer) + 150 ms ± 50 ms, as the page asks
    for it: a 640x480 JPEG camera at 10 Hz, and the rover's own camera, arrive fresh and do not
    fall behind. The ages are the page's own (arrival - stamp)."""
    seconds = 10   # a camera that queues is seconds behind by then (the old options: 5 s at 10 s)
    with netlink.NetLink(delay=DELAY, jitter=JITTER, rate=125_000, buffer=64 * 1024) as link:
        gw = link.start_gateway('--robot', 'rover' if camera == 'rover' else 'turtlesim')
        stop = threading.Event()
        publishing = (camera_publisher(link, gw, '/camera/image_raw/compressed', stop)
                      if camera != 'rover' else None)
        try:
            with nullcontext(playwright) as p:
                browser = p.chromium.launch(executable_path=str(link.chromium_wrapper(CHROMIUM, tmp_path)),
                                            args=CHROMIUM_ARGS)
                try:
                    page = page_state.install(browser.new_page(viewport={'width': 390, 'height': 844}))
                    page.goto(gw.http_url + 'teleop', timeout=60000)
                    page.wait_for_function("window.teleop?.frames >= 5", timeout=60000, polling=100)
                    page.evaluate(CAMERA_AGES)
                    page.wait_for_function(f"cameraAges.length && Date.now() / 1000 - cameraAges[0][0] >= {seconds}",
                                           timeout=(seconds + 60) * 1000, polling=250)
                    ages = page.evaluate('cameraAges')
                    size = page.evaluate("document.querySelector('#camera-info').textContent")
                finally:
                    browser.close()
        finally:
            stop.set()
            if publishing:
                publishing.join(2)
    span = ages[-1][0] - ages[0][0]
    fps = (len(ages) - 1) / span
    values = sorted(a for _, a in ages)
    p50, p95 = values[len(values) // 2], values[int(len(values) * 0.95)]
    third = [a for t, a in ages if t >= ages[0][0] + 2 * span / 3]
    last_p95 = sorted(third)[int(len(third) * 0.95)]
    print(f'\nteleop camera ({camera}) at 1 Mbit/s + 150 ms: {fps:.1f} frames/s, age p50 {p50:.2f} s, '
          f'p95 {p95:.2f} s, last third p95 {last_p95:.2f} s, max {values[-1]:.2f} s ({size})')
    # The bars (a 640x480 camera p95 <= 1 s; the rover's >= 4.5 frames/s, p95 <= 0.5 s) are the
    # figures printed above, on a quiet machine. The bounds here hold on a busy one and still fail
    # a camera that queues: the page's old options had p95 5.2 s and growing on this line.
    assert fps >= 2.0, fps
    assert p95 <= 2.5 and last_p95 <= 2.5, (p95, last_p95)
