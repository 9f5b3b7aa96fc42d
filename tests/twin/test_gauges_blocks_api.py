"""The gauges' limits (/api/gauges, --gauges FILE) and the block sets' API (/api/blocks,
--blocks-dir) over real HTTP to a real gateway: what a file gives, what a bad request gets."""

from __future__ import annotations

import json

from tests.support.http import api, http


def test_gauge_limits_from_a_json_file_read_on_each_request(start_gateway, tmp_path):
    path = tmp_path / "gauges.json"
    path.write_text(json.dumps({"/r1/battery_state": {"warn": 40, "danger": 15, "low": True},
                                "motor/*/temperature": {"max": 120}}))
    gw = start_gateway("--gauges", str(path))
    status, body = api(gw, "GET", "/api/gauges")
    assert status == 200 and body["limits"]["/r1/battery_state"] == {"warn": 40, "danger": 15, "low": True}
    path.write_text(json.dumps({"/r1/battery_state": {"warn": 30}}))   # a changed limit, no restart
    assert api(gw, "GET", "/api/gauges")[1] == {"limits": {"/r1/battery_state": {"warn": 30}}}
    path.write_text(json.dumps({"/r1/battery_state": {"warn": "high"}}))   # broken since: said, not served
    status, body = api(gw, "GET", "/api/gauges")
    assert status == 500 and "'warn' is not a number" in body["error"], body


def test_no_files_no_limits_no_sets(start_gateway):
    gw = start_gateway()
    assert api(gw, "GET", "/api/gauges") == (200, {"limits": {}})
    assert api(gw, "GET", "/api/blocks") == (200, {"sets": [], "shared": [], "publish": False})
    status, body = api(gw, "POST", "/api/blocks/shared", {"json": {"type": "a"}, "spec": {}})
    assert status == 404 and "--blocks-dir" in body["error"]


def test_sets_listed_and_made_blocks_published_one_per_type(start_gateway, tmp_path):
    (tmp_path / "arm.json").write_text(json.dumps({"name": "Arm", "robot": "/arm*", "blocks": [{"type": "arm_wave"}]}))
    (tmp_path / "bad_type.json").write_text(json.dumps({"blocks": [{"type": "no spaces allowed"}]}))
    gw = start_gateway("--blocks-dir", str(tmp_path))
    status, body = api(gw, "GET", "/api/blocks")
    assert status == 200 and [s["name"] for s in body["sets"]] == ["Arm"] and body["sets"][0]["robot"] == "/arm*"
    assert body["skipped"][0]["file"] == "bad_type.json" and body["publish"] is True   # no --auth: everyone an admin
    made = {"json": {"type": "my_publish_x", "message0": "x"}, "spec": {"kind": "publish", "topic": "/x"}}
    assert api(gw, "POST", "/api/blocks/shared", made) == (200, {"type": "my_publish_x", "shared": 1})
    again = {**made, "json": {**made["json"], "message0": "x again"}}
    assert api(gw, "POST", "/api/blocks/shared", again) == (200, {"type": "my_publish_x", "shared": 1})
    assert api(gw, "GET", "/api/blocks")[1]["shared"] == [again]
    for bad in ({"json": {"type": "a b"}, "spec": {}}, {"json": {"type": "ok"}}, {"spec": {}}):
        status, body = api(gw, "POST", "/api/blocks/shared", bad)
        assert status == 400, (bad, body)
    reply = http(gw, "/api/blocks/shared", method="POST", data=b"{}", headers={"Content-Type": "text/plain"})
    assert reply.status == 415
    assert json.loads((tmp_path / "shared.json").read_text()) == {"made": [again]}
