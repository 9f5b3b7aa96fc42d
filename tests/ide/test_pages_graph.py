"""The pages subscribe only to what the robot publishes, in Chromium, on ``--robot turtlesim``: a
teleop visit leaves the graph as it was (the rover's /battery_state, /odom and motor temperatures
once stayed listed after it, and the history kept them), the twin then draws the turtle (not the
rover those names suggested) and asks for no /urdf, and a topic that appears later is shown once it
is published. The graph is read by an independent roslibpy client."""

from __future__ import annotations

import pytest
import roslibpy

from tests.support.http import api
from tests.support.ide import TABLET
from tests.support.ros import client
from tests.support.wait import wait_for

READY = "document.body?.dataset.ready === 'true' && document.body.dataset.connection === 'connected'"


@pytest.fixture(scope='module')
def turtle(launch):
    return launch('--robot', 'turtlesim')


def topics(gw) -> set[str]:
    with client(gw) as ros:
        return set(roslibpy.Service(ros, '/rosapi/topics', 'rosapi/Topics').call(
            roslibpy.ServiceRequest({}), timeout=10)['topics'])


def open_page(chromium, gw, path: str):
    ctx = chromium.new_context(viewport=TABLET)
    page = ctx.new_page()
    page.problems = []
    page.requests = []
    page.on('pageerror', lambda e: page.problems.append(f'error: {e}'))
    page.on('console', lambda m: m.type == 'error' and page.problems.append(f'console: {m.text}'))
    page.on('requestfailed', lambda r: page.problems.append(f'failed: {r.url}'))
    page.on('response', lambda r: r.status >= 400 and page.problems.append(f'{r.status}: {r.url}'))
    page.on('request', lambda r: page.requests.append(r.url))
    page.goto(gw.http_url + path)
    page.wait_for_function(READY, timeout=30000)
    return ctx, page


def test_a_teleop_visit_invents_no_topic_and_the_twin_draws_the_turtle(turtle, chromium):
    gw = turtle
    before = topics(gw)
    ctx, page = open_page(chromium, gw, 'teleop')
    try:
        page.wait_for_function('window.teleop.graph !== undefined', timeout=30000)   # it read the graph
        page.wait_for_function("document.querySelector('#world-card').hidden === false", timeout=30000)
        # what it subscribed to: only published topics (its world), nothing of the rover's
        subscribed = page.evaluate('window.teleop.subs.map((s) => s.topic)')
        assert not [t for t in subscribed if t not in before], subscribed
        assert topics(gw) == before
        assert page.evaluate("[...document.querySelectorAll('#battery-card, #camera-card')].every((e) => e.hidden)")
        assert not page.problems, page.problems
    finally:
        ctx.close()
    assert topics(gw) == before
    kept = api(gw, 'GET', '/api/history/stats')[1]['topics']
    assert kept == ['/turtle1/pose'], kept

    ctx, page = open_page(chromium, gw, 'twin')
    try:
        page.wait_for_function("twin.state.model !== null || twin.state.error", timeout=30000)
        assert page.evaluate('twin.state.model') == 'turtle'
        assert page.evaluate('twin.state.urdfFrom') is None
        assert not [u for u in page.requests if u.rstrip('/').endswith('/urdf')], page.requests
        assert any('/api/description' in u for u in page.requests)
        assert topics(gw) == before
        assert not page.problems, page.problems
    finally:
        ctx.close()


def test_a_topic_published_later_is_shown_then(turtle, chromium):
    """A battery that starts publishing after the page: its gauge appears at the page's next look."""
    gw = turtle
    ctx, page = open_page(chromium, gw, 'teleop')
    try:
        page.wait_for_function('window.teleop.graph !== undefined', timeout=30000)
        assert page.evaluate("document.querySelector('#g-battery').hidden")
        with client(gw) as ros:
            battery = roslibpy.Topic(ros, '/battery_state', 'sensor_msgs/msg/BatteryState')
            battery.advertise()

            def shown():
                battery.publish(roslibpy.Message({'percentage': 0.42, 'voltage': 12.1}))
                return page.evaluate("Math.round(Number(document.querySelector('#g-battery').dataset.value)) === 42 && !document.querySelector('#g-battery').hidden")
            wait_for(shown, timeout=40, interval=0.5, what='the battery gauge after the next look')
            battery.unadvertise()
    finally:
        ctx.close()
