"""The program library HTTP API (/api/programs), black-box against a live gateway."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from tests.support.http import http

PROGRAM = {"format": "rosgate-program", "version": 1, "name": "square",
           "workspace": {"blocks": {"languageVersion": 0, "blocks": [{"type": "ros_stop"}]}}}
JSON = {"Content-Type": "application/json"}


def names(gateway) -> list[str]:
    status, body, _ = http(gateway, "/api/programs")
    assert status == 200
    return [p["name"] for p in json.loads(body)["programs"]]


def test_save_list_load_delete(gateway):
    status, body, _ = http(gateway, "/api/programs/my%20square", method="PUT", json=PROGRAM)
    assert status == 200, body
    assert json.loads(body)["name"] == "my square"
    assert "my square" in names(gateway)
    listing = json.loads(http(gateway, "/api/programs")[1])["programs"]
    entry = next(p for p in listing if p["name"] == "my square")
    assert entry["size"] > 0 and entry["modified"] > 0

    status, body, _ = http(gateway, "/api/programs/my%20square")
    assert status == 200
    assert json.loads(body) == PROGRAM
    assert (Path(gateway.programs_dir) / "my square.json").is_file()

    # saving again replaces
    changed = {**PROGRAM, "name": "square 2"}
    assert http(gateway, "/api/programs/my%20square", method="PUT", json=changed)[0] == 200
    assert json.loads(http(gateway, "/api/programs/my%20square")[1])["name"] == "square 2"

    status, *_ = http(gateway, "/api/programs/my%20square", method="DELETE")
    assert status == 204
    assert "my square" not in names(gateway)
    assert http(gateway, "/api/programs/my%20square")[0] == 404
    assert http(gateway, "/api/programs/my%20square", method="DELETE")[0] == 404


@pytest.mark.parametrize("name", [
    "..%2F..%2Fetc%2Fpasswd", "%2E%2E", "a%2Fb", ".hidden", "%20lead", "x" * 65, "semi%3Bcolon", "dot.json",
])
def test_unsafe_names_refused(gateway, name):
    before = set(os.listdir(gateway.programs_dir)) if os.path.isdir(gateway.programs_dir) else set()
    status, body, _ = http(gateway, f"/api/programs/{name}", method="PUT", json=PROGRAM)
    assert status in (400, 404), (status, body)
    if status == 400:
        assert "name" in json.loads(body)["error"]
    after = set(os.listdir(gateway.programs_dir)) if os.path.isdir(gateway.programs_dir) else set()
    assert after == before
    assert http(gateway, f"/api/programs/{name}")[0] in (400, 404)


def test_traversal_does_not_escape(gateway):
    secret = Path(gateway.programs_dir).parent / "rosgate-secret-test.json"
    secret.write_text('{"token": "TOPSECRET-42"}')
    try:
        for path in ("/api/programs/..%2Frosgate-secret-test", "/api/programs/../rosgate-secret-test"):
            status, body, _ = http(gateway, path)
            assert b"TOPSECRET-42" not in body
            assert status in (400, 403, 404)
    finally:
        secret.unlink()


@pytest.mark.parametrize("body", [b"not json", b"[1, 2]", b'"text"', b"{"])
def test_bad_bodies_refused(gateway, body):
    status, reply, _ = http(gateway, "/api/programs/bad", method="PUT", data=body, headers=JSON)
    assert status == 400
    assert json.loads(reply)["error"]
    assert "bad" not in names(gateway)


def test_too_large_refused(gateway):
    big = json.dumps({"format": "rosgate-program", "pad": "x" * (3 * 1024 * 1024)}).encode()
    status, *_ = http(gateway, "/api/programs/big", method="PUT", data=big, headers=JSON)
    assert status == 413
    assert "big" not in names(gateway)
    assert gateway.alive


@pytest.mark.parametrize("owner", ["..", "../..", "a/b", ".hidden", "%2E%2E%2F%2E%2E", "x" * 70])
def test_owner_spaces_stay_inside_the_library(gateway, owner):
    """?owner= picks a space under users/; a name unsafe as a directory becomes u-<digest>."""
    root = Path(gateway.programs_dir)
    outside = set(os.listdir(root.parent))
    status, body, _ = http(gateway, f"/api/programs/escape?owner={owner}", method="PUT", json=PROGRAM)
    assert status == 200, body
    assert set(os.listdir(root.parent)) == outside
    stored = [p for p in (root / "users").rglob("escape.json")]
    assert len(stored) == 1 and stored[0].parent.parent == root / "users", stored
    assert stored[0].parent.name.startswith("u-")
    listing = json.loads(http(gateway, "/api/programs")[1])["programs"]
    assert any(p["name"] == "escape" and p["owner"] == stored[0].parent.name for p in listing)
    assert http(gateway, f"/api/programs/escape?owner={owner}", method="DELETE")[0] == 204


def test_another_sites_page_cannot_change_the_library(gateway):
    """A form on another site can post text/plain and carries that site's Origin: neither a
    write nor a delete from such a request changes the library."""
    assert http(gateway, "/api/programs/kept", method="PUT", json=PROGRAM)[0] == 200
    form = json.dumps({"format": "rosgate-program", "evil": True}).encode()
    status, reply, _ = http(gateway, "/api/programs/kept", method="POST", data=form,
                            headers={"Content-Type": "text/plain"})
    assert status == 415, reply
    for method, body in (("PUT", json.dumps(PROGRAM).encode()), ("POST", form), ("DELETE", None)):
        refused = http(gateway, "/api/programs/kept", method=method, data=body,
                       headers={"Origin": "http://evil.example", **JSON})
        assert refused.status == 403, method
        assert b"evil.example" in refused.body
    status, body, _ = http(gateway, "/api/programs/kept")
    assert status == 200 and json.loads(body) == PROGRAM
    own = gateway.http_url.rstrip("/")   # the gateway's own pages may
    assert http(gateway, "/api/programs/kept", method="DELETE", headers={"Origin": own}).status == 204
