"""The gateway's node name: rosgate_<host>_<port> by default, so gateways on one graph differ."""

from __future__ import annotations

import re

from gateway.cli import default_node_name
from tests.support.rawclient import Raw

VALID = re.compile(r'[A-Za-z_][A-Za-z0-9_]*')   # a ROS node name (rmw_validate_node_name)


def test_the_default_name_holds_host_and_port_and_is_a_valid_node_name():
    assert default_node_name(9090, 'turtlebot4') == 'rosgate_turtlebot4_9090'
    assert default_node_name(9091, 'robot-1.lab.example.org') == 'rosgate_robot_1_9091'
    for host in ('', '-', 'Ünïcode-host', '9lives', 'a__b'):
        name = default_node_name(8080, host)
        assert VALID.fullmatch(name) and '__' not in name and name.endswith('_8080'), (host, name)


def test_the_running_gateway_is_the_node_its_startup_line_names(gateway):
    assert gateway.node == '/' + default_node_name(gateway.port)
    with Raw(gateway.ws_url) as raw:
        assert gateway.node in raw.call('/rosapi/nodes')['values']['nodes']
