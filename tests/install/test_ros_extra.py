"""`pip install 'rosgate[ros]'`: the rosgate command of that environment bridges the ROS 2 graph.

`make test-rclpy` runs this in .venv-ros (the project installed as `.[ros]`) inside a network
namespace with only loopback; where rclpy does not import it is skipped."""

from __future__ import annotations

import asyncio
import json
import sys
import urllib.request
from pathlib import Path

import pytest

from tests.support.install import started

try:
    import rclpy  # noqa: F401
except ImportError as e:   # the main test environment has no rclpy
    pytest.skip(f'rclpy does not import here: {e}', allow_module_level=True)


def test_rosgate_command_starts_on_rclpy_and_bridges_the_graph(tmp_path):
    gw = started([Path(sys.executable).parent / 'rosgate', '--backend', 'rclpy', '--port', '0',
                  '--address', '127.0.0.1', '--programs-dir', tmp_path / 'programs'], cwd=tmp_path)
    try:
        assert ' backend rclpy ' in gw.line, gw.line
        with urllib.request.urlopen(gw.http_url + 'health', timeout=10) as r:
            assert json.load(r)['backend'] == 'rclpy'
        topics = asyncio.run(rosapi_topics(gw.port))
        # the gateway's own publisher, seen through the ROS graph
        assert '/client_count' in topics['topics']
    finally:
        gw.stop()
    assert gw.proc.returncode == 0


async def rosapi_topics(port: int) -> dict:
    from tornado.websocket import websocket_connect
    ws = await websocket_connect(f'ws://127.0.0.1:{port}/')
    try:
        ws.write_message(json.dumps({'op': 'call_service', 'id': 't', 'service': '/rosapi/topics', 'args': {}}))
        while True:
            reply = json.loads(await asyncio.wait_for(ws.read_message(), 20))
            if reply.get('op') == 'service_response' and reply.get('id') == 't':
                assert reply['result'], reply
                return reply['values']
    finally:
        ws.close()
