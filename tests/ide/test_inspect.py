"""/inspect in Chromium against the sim's turtlesim and rover: what a student sees (topics with their types and
rates, a live echo she can pause, the nodes and what each does, the graph, the /rosout log) and what
she does there (a parameter set, a plot and its CSV, a message published, a service called), each
checked by an independent roslibpy client. Elements are found by id and data attributes, not words.
The same page in WebKit and Firefox: test_engines.py."""

from __future__ import annotations

import pytest

from tests.support.ide import PHONE, TABLET
from tests.support.ros import RosClient
from tests.support.wait import wait_for

READY = "document.body?.dataset.ready === 'true' && document.body.dataset.connection === 'connected'"
ROW = "document.querySelector(\"#topics tbody tr[data-topic='{}']\")"


@pytest.fixture(scope="module")
def lab(start_gateway):
    return start_gateway("--robot", "turtlesim", "--robot", "rover", "--talker")


@pytest.fixture(scope="module")
def context(chromium):
    ctx = chromium.new_context(viewport=TABLET, has_touch=True, accept_downloads=True)
    yield ctx
    ctx.close()


@pytest.fixture
def ros(lab):
    c = RosClient(lab)
    yield c
    c.close()


def open_inspect(context, lab):
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(lab.http_url + "inspect")
    page.wait_for_function(READY)
    return page, errors


def test_topics_echo_nodes_graph_and_log(context, lab, ros):
    page, errors = open_inspect(context, lab)
    try:
        pose = ROW.format("/turtle1/pose")
        page.wait_for_function(f"{pose}?.querySelector('td.type').textContent === 'turtlesim/msg/Pose'")
        page.eval_on_selector("#topics tbody tr[data-topic='/turtle1/pose']", "r => r.scrollIntoView({block: 'nearest'})")
        page.wait_for_function(f"Number({pose}.dataset.rate) > 0 && {pose}.querySelector('td.pubs').textContent === '1'")
        assert "Hz" in page.eval_on_selector("#topics tbody tr[data-topic='/turtle1/pose'] td.rate", "e => e.textContent")
        assert page.text_content("#topics tbody tr[data-topic='/chatter'] td.type") == "std_msgs/msg/String"

        # the echo of /chatter: live, then paused, then live again
        page.click("#topics tbody tr[data-topic='/chatter']")
        page.wait_for_function("document.querySelector('#echo-card').dataset.topic === '/chatter'"
                               " && Number(document.querySelector('#echo-card').dataset.count) >= 1")
        first = page.text_content("#echo-tree")
        assert "Hello World" in first
        page.wait_for_function("t => document.querySelector('#echo-tree').textContent !== t", arg=first, timeout=20000)
        page.click("#echo-pause")
        page.wait_for_function("document.querySelector('#echo-card').dataset.paused === 'true'")
        paused = page.get_attribute("#echo-card", "data-count")
        chatter = ros.watch("/chatter", "std_msgs/msg/String")
        wait_for(lambda: len(chatter.messages) >= 2, timeout=20, what="two more /chatter messages")
        assert page.get_attribute("#echo-card", "data-count") == paused
        page.click("#echo-pause")
        page.wait_for_function(f"Number(document.querySelector('#echo-card').dataset.count) > {paused}", timeout=20000)

        # a camera's echo is its picture, made to measure by the gateway (at most 480 wide)
        page.click("#topics tbody tr[data-topic='/camera/image_raw/compressed'] td.name")
        page.wait_for_function("document.querySelector('#echo-image').naturalWidth > 0 && !document.querySelector('#echo-image').hidden")
        assert 0 < page.evaluate("document.querySelector('#echo-image').naturalWidth") <= 480
        assert "data" not in page.eval_on_selector_all("#echo-tree .k", "ks => ks.map(k => k.textContent)")

        # the nodes: what turtlesim publishes, subscribes to, serves; its parameters
        page.click("#nodes button[data-node='/turtlesim']")
        page.wait_for_function("document.querySelector('#params-box').dataset.params > 0")
        details = page.eval_on_selector("#node-details", """d => Object.fromEntries([...d.querySelectorAll('.group')].map(
            g => [g.dataset.kind, [...g.querySelectorAll('li')].map(li => li.textContent)]))""")
        assert "/turtle1/pose" in details["publishing"] and "/turtle1/cmd_vel" in details["subscribing"]
        assert "/spawn" in details["services"] and "/turtlesim/set_parameters" not in details["services"]
        assert details["actions"] == ["/turtle1/rotate_absolute"]
        assert page.query_selector("#params tr[data-param='background_r']") is not None

        # the graph, drawn once in view; a tap lights a node's links
        page.locator("#graph-card").scroll_into_view_if_needed()
        page.wait_for_function("document.querySelector(\"#graph .vertex[data-id='n:/turtlesim']\") !== null")
        assert int(page.get_attribute("#graph-card", "data-edges")) > 3
        page.click("#graph .vertex[data-id='n:/talker']")
        lit = page.eval_on_selector_all("#graph .edge.lit", "es => es.map(e => [e.dataset.from, e.dataset.to])")
        assert lit == [["n:/talker", "t:/chatter"]]

        # the log: turtlesim's lines (a spawn's among them), by level and by search
        ros.call("/spawn", "turtlesim/srv/Spawn", {"x": 2.0, "y": 2.0, "theta": 0.0, "name": ""})
        ros.call("/reset_world", "std_srvs/srv/Empty")   # the rover says so in its log
        page.wait_for_function("[...document.querySelectorAll(\"#log li[data-node='turtlesim']\")]"
                               ".some(li => li.textContent.includes('Spawning turtle'))")
        page.select_option("#log-level", "30")
        page.wait_for_function("![...document.querySelectorAll('#log li')].some(li => li.dataset.level === 'info')")
        page.select_option("#log-level", "20")
        page.wait_for_function("[...document.querySelector('#log-node').options].some(o => o.value === 'rover')")
        page.select_option("#log-node", "rover")
        assert set(page.eval_on_selector_all("#log li", "ls => ls.map(l => l.dataset.node)")) <= {"rover"}
        page.select_option("#log-node", "")
        page.fill("#log-search", "Spawning")
        texts = page.eval_on_selector_all("#log li", "ls => ls.map(l => l.textContent)")
        assert texts and all("Spawning" in t for t in texts)
        assert not errors, errors
    finally:
        page.close()


def test_parameters_plot_publish_and_call(context, lab, ros):
    page, errors = open_inspect(context, lab)
    try:
        # a parameter set through the node's own service
        page.click("#nodes button[data-node='/turtlesim']")
        row = "#params tr[data-param='background_g']"
        page.wait_for_selector(f"{row} input")
        page.fill(f"{row} input", "not a number")
        page.click(f"{row} button")
        page.wait_for_function(f"document.querySelector(\"{row}\").dataset.result === 'invalid'")
        page.fill(f"{row} input", "42")
        page.click(f"{row} button")
        page.wait_for_function(f"document.querySelector(\"{row}\").dataset.result === 'set'")
        assert ros.call("/rosapi/get_param", "rosapi_msgs/srv/GetParam", {"name": "/turtlesim:background_g"})["value"] == "42"

        # a plot of the turtle's x, and its rows as CSV
        page.fill("#plot-topic", "/turtle1/pose")
        page.dispatch_event("#plot-topic", "change")
        page.wait_for_function("[...document.querySelector('#plot-field').options].some(o => o.value === 'x')")
        page.select_option("#plot-field", "x")
        page.click("#plot-add")
        page.wait_for_function("Number(document.querySelector('#plot-card').dataset.rows) >= 5")
        assert page.query_selector("#plot canvas") is not None
        with page.expect_download() as got:
            page.click("#plot-csv")
        lines = open(got.value.path()).read().splitlines()
        assert lines[0] == "time,unix,/turtle1/pose x" and len(lines) >= 6
        assert all(float(line.split(",")[2]) >= 0 for line in lines[1:] if line.split(",")[2])
        with page.expect_download() as got:
            page.click("#plot-png")
        assert open(got.value.path(), "rb").read(8) == b"\x89PNG\r\n\x1a\n"

        # a Twist published from its form reaches the turtle's topic
        cmd = ros.watch("/turtle1/cmd_vel", "geometry_msgs/msg/Twist")
        page.fill("#pub-topic", "/turtle1/cmd_vel")
        page.dispatch_event("#pub-topic", "change")
        page.wait_for_function("document.querySelector('#pub').dataset.ready === 'geometry_msgs/msg/Twist'")
        page.fill("#pub-form input[name='linear.x']", "0.5")
        page.fill("#pub-form input[name='angular.z']", "oops")
        page.click("#pub-send")
        page.wait_for_function("document.querySelector('#pub').dataset.result === 'refused'")   # the form says which field
        assert page.get_attribute("#pub-form input[name='angular.z']", "aria-invalid") == "true"
        page.fill("#pub-form input[name='angular.z']", "0.25")
        page.click("#pub-send")
        page.wait_for_function("document.querySelector('#pub').dataset.result === 'published'")
        sent = wait_for(cmd.latest, what="the published Twist")
        assert sent["linear"]["x"] == 0.5 and sent["angular"]["z"] == 0.25

        # a service called from its request's form
        page.fill("#call-service", "/add_two_ints")
        page.dispatch_event("#call-service", "change")
        page.wait_for_function("document.querySelector('#call').dataset.ready === 'example_interfaces/srv/AddTwoInts'")
        page.fill("#call-form input[name='a']", "2")
        page.fill("#call-form input[name='b']", "40")
        page.click("#call-send")
        page.wait_for_function("document.querySelector('#call').dataset.result === 'answered'")
        assert page.eval_on_selector("#call-result .leaf", "l => [l.querySelector('.k').textContent, l.querySelector('.v').textContent]") == ["sum", "42"]
        assert not errors, errors
    finally:
        page.close()


def test_a_phone_reads_the_same_page(chromium, lab):
    ctx = chromium.new_context(viewport=PHONE, has_touch=True, is_mobile=True)
    try:
        page = ctx.new_page()
        page.goto(lab.http_url + "inspect")
        page.wait_for_function(READY)
        first = "document.querySelector('#topics tbody tr:first-child')"
        page.wait_for_function(f"Number({first}?.dataset.rate) >= 0")
        assert page.evaluate("document.documentElement.scrollWidth <= innerWidth + 1"), "the page scrolls sideways"
        assert page.is_visible("#jump") and page.is_visible("#topics tbody tr:first-child td.type")
        assert not page.is_visible("#topics tbody tr:first-child td.bw")   # room for the rate
        # only the rows in view are measured: the last one when it is scrolled to
        last = "document.querySelector('#topics tbody tr:last-child')"
        page.wait_for_function(f"Number({first}.dataset.rate) >= 0 && Number({first}.dataset.pubs) >= 0")   # asked again since
        assert page.evaluate(f"{last}.dataset.rate") is None
        page.eval_on_selector("#topics tbody tr:last-child", "r => r.scrollIntoView()")
        page.wait_for_function(f"{last}.dataset.rate !== undefined")
        page.click("#jump a[href='#nodes-card']")
        page.wait_for_function("document.querySelector(\"#nodes button[data-node='/turtlesim']\") !== null")
    finally:
        ctx.close()
