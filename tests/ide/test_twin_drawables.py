"""What /twin draws of a real robot besides its model, in Chromium's software WebGL: the rover's 3D
lidar (sensor_msgs/PointCloud2, thinned by the gateway to what the page asks for), markers of every
visualization_msgs/Marker type on a topic of their own (with DELETE, DELETEALL and lifetimes), and a
goal (geometry_msgs/PoseStamped on /goal_pose, as RViz's "2D Goal Pose" sends it) where TF puts its
frame. The markers and the goal come from an independent roslibpy client, as from another node."""

from __future__ import annotations

import roslibpy

from tests.support.ide import ARTIFACTS
from tests.support.wait import wait_for

from .test_twin import WAIT, phone_page

MARKERS = "/debug/markers"
ALL_TYPES = list(range(12))   # ARROW .. TRIANGLE_LIST


def marker(id_: int, type_: int, **kw) -> dict:
    m = {"header": {"frame_id": "world"}, "ns": "debug", "id": id_, "type": type_, "action": 0,
         "pose": {"position": {"x": 1.0 + 0.5 * id_, "y": 1.0, "z": 0.2}, "orientation": {"x": 0, "y": 0, "z": 0, "w": 1}},
         "scale": {"x": 0.3, "y": 0.1, "z": 0.1}, "color": {"r": 0.2, "g": 0.8, "b": 1.0, "a": 1.0}}
    if type_ in (0, 4, 5, 6, 7, 8, 11):
        m["points"] = [{"x": 0.0, "y": 0.0, "z": 0.0}, {"x": 0.3, "y": 0.0, "z": 0.0}, {"x": 0.0, "y": 0.3, "z": 0.0}]
        m["colors"] = [{"r": 1.0, "g": 0.0, "b": 0.0, "a": 1.0}] * 3
    if type_ == 9:
        m["text"] = "hello"
    m.update(kw)
    return m


def test_clouds_markers_and_goals(chromium, rover):
    gw, ros = rover
    markers = roslibpy.Topic(ros.ros, MARKERS, "visualization_msgs/msg/MarkerArray", latch=True)
    goal = roslibpy.Topic(ros.ros, "/goal_pose", "geometry_msgs/msg/PoseStamped", latch=True)
    markers.advertise()
    goal.advertise()
    wait_for(lambda: {MARKERS, "/goal_pose"} <= set(ros.ros.get_topics()), what="the topics on the graph")
    markers.publish(roslibpy.Message({"markers": [marker(i, t) for i, t in enumerate(ALL_TYPES)]}))
    goal.publish(roslibpy.Message({"header": {"frame_id": "world"},
                                   "pose": {"position": {"x": 2.5, "y": 1.5, "z": 0.0}, "orientation": {"x": 0, "y": 0, "z": 0.7071068, "w": 0.7071068}}}))
    try:
        with phone_page(chromium, gw.http_url + "twin") as (page, errors):
            page.wait_for_function("document.body.dataset.ready === 'true' && twin.drawables", timeout=WAIT)
            # the lidar: at most the points the page asked for, placed in lidar_link by TF (0.25 m up)
            page.wait_for_function("(twin.drawables.state.clouds['/points'] || 0) > 500", timeout=WAIT)
            n = page.evaluate("twin.drawables.state.clouds['/points']")
            assert n <= 4000, n
            z = page.evaluate("twin.drawables.clouds.get('/points').holder.position.z")
            assert abs(z - 0.25) < 1e-6, z
            # every marker type drawn
            page.wait_for_function(f"Object.keys(twin.drawables.state.types).length === {len(ALL_TYPES)}", timeout=WAIT)
            # the goal where it was sent, facing +y
            page.wait_for_function("twin.drawables.state.goals === 1", timeout=WAIT)
            g = page.evaluate("({x: twin.drawables.state.goal.x, y: twin.drawables.state.goal.y}) ")
            assert abs(g["x"] - 2.5) < 1e-6 and abs(g["y"] - 1.5) < 1e-6, g
            page.screenshot(path=str(ARTIFACTS / "twin-drawables-phone.png"))

            # one deleted, one that lives a second, then all of the namespace gone
            markers.publish(roslibpy.Message({"markers": [{**marker(0, 0), "action": 2},
                                                          marker(20, 2, lifetime={"sec": 1, "nanosec": 0})]}))
            page.wait_for_function("twin.drawables.state.markers === 12 && !twin.drawables.state.types[0]", timeout=WAIT)
            page.wait_for_function("twin.drawables.state.markers === 11", timeout=WAIT)   # the sphere's second is over
            markers.publish(roslibpy.Message({"markers": [{**marker(0, 0), "action": 3}]}))
            page.wait_for_function("twin.drawables.state.markers === 0", timeout=WAIT)
            assert not errors, errors
    finally:
        markers.unadvertise()
        goal.unadvertise()
