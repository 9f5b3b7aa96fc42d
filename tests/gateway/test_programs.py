"""The program library HTTP API (/api/programs), black-box against a live gateway."""

from __future__ import annotations

import json
import os
import urllib.error
import urllib.request
from pathlib import Path

import pytest

PROGRAM = {"format": "rosgate-program", "version": 1, "name": "square",
           "workspace": {"blocks": {"languageVersion": 0, "blocks": [{"type": "ros_stop"}]}}}


def request(gateway, method: str, path: str, body: bytes | None = None,
            content_type: str = "application/json") -> tuple[int, bytes]:
    req = urllib.request.Request(gateway.http_url.rstrip("/") + path, data=body, method=method)
    if body is not None:
        req.add_header("Content-Type", content_type)
    try:
        with urllib.request.urlopen(req, timeout=5) as res:
            return res.status, res.read()
    except urllib.error.HTTPError as e:
        return e.code, e.read()


def names(gateway) -> list[str]:
    status, body = request(gateway, "GET", "/api/programs")
    assert status == 200
    return [p["name"] for p in json.loads(body)["programs"]]


def test_save_list_load_delete(gateway):
    status, body = request(gateway, "PUT", "/api/programs/my%20square", json.dumps(PROGRAM).encode())
    assert status == 200, body
    assert json.loads(body)["name"] == "my square"
    assert "my square" in names(gateway)
    listing = json.loads(request(gateway, "GET", "/api/programs")[1])["programs"]
    entry = next(p for p in listing if p["name"] == "my square")
    assert entry["size"] > 0 and entry["modified"] > 0

    status, body = request(gateway, "GET", "/api/programs/my%20square")
    assert status == 200
    assert json.loads(body) == PROGRAM
    assert (Path(gateway.programs_dir) / "my square.json").is_file()

    # saving again replaces
    changed = {**PROGRAM, "name": "square 2"}
    assert request(gateway, "PUT", "/api/programs/my%20square", json.dumps(changed).encode())[0] == 200
    assert json.loads(request(gateway, "GET", "/api/programs/my%20square")[1])["name"] == "square 2"

    status, _ = request(gateway, "DELETE", "/api/programs/my%20square")
    assert status == 204
    assert "my square" not in names(gateway)
    assert request(gateway, "GET", "/api/programs/my%20square")[0] == 404
    assert request(gateway, "DELETE", "/api/programs/my%20square")[0] == 404


@pytest.mark.parametrize("name", [
    "..%2F..%2Fetc%2Fpasswd", "%2E%2E", "a%2Fb", ".hidden", "%20lead", "x" * 65, "semi%3Bcolon", "dot.json",
])
def test_unsafe_names_refused(gateway, name):
    before = set(os.listdir(gateway.programs_dir)) if os.path.isdir(gateway.programs_dir) else set()
    status, body = request(gateway, "PUT", f"/api/programs/{name}", json.dumps(PROGRAM).encode())
    assert status in (400, 404), (status, body)
    if status == 400:
        assert "name" in json.loads(body)["error"]
    after = set(os.listdir(gateway.programs_dir)) if os.path.isdir(gateway.programs_dir) else set()
    assert after == before
    assert request(gateway, "GET", f"/api/programs/{name}")[0] in (400, 404)


def test_traversal_does_not_escape(gateway):
    secret = Path(gateway.programs_dir).parent / "rosgate-secret-test.json"
    secret.write_text('{"token": "TOPSECRET-42"}')
    try:
        for path in ("/api/programs/..%2Frosgate-secret-test", "/api/programs/../rosgate-secret-test"):
            status, body = request(gateway, "GET", path)
            assert b"TOPSECRET-42" not in body
            assert status in (400, 403, 404)
    finally:
        secret.unlink()


@pytest.mark.parametrize("body", [b"not json", b"[1, 2]", b'"text"', b"{"])
def test_bad_bodies_refused(gateway, body):
    status, reply = request(gateway, "PUT", "/api/programs/bad", body)
    assert status == 400
    assert json.loads(reply)["error"]
    assert "bad" not in names(gateway)


def test_too_large_refused(gateway):
    big = json.dumps({"format": "rosgate-program", "pad": "x" * (3 * 1024 * 1024)}).encode()
    status, _ = request(gateway, "PUT", "/api/programs/big", big)
    assert status == 413
    assert "big" not in names(gateway)
    assert gateway.alive


@pytest.mark.parametrize("owner", ["..", "../..", "a/b", ".hidden", "%2E%2E%2F%2E%2E", "x" * 70])
def test_owner_spaces_stay_inside_the_library(gateway, owner):
    """?owner= picks a space under users/; a name unsafe as a directory becomes u-<digest>."""
    root = Path(gateway.programs_dir)
    outside = set(os.listdir(root.parent))
    status, body = request(gateway, "PUT", f"/api/programs/escape?owner={owner}", json.dumps(PROGRAM).encode())
    assert status == 200, body
    assert set(os.listdir(root.parent)) == outside
    stored = [p for p in (root / "users").rglob("escape.json")]
    assert len(stored) == 1 and stored[0].parent.parent == root / "users", stored
    assert stored[0].parent.name.startswith("u-")
    listing = json.loads(request(gateway, "GET", "/api/programs")[1])["programs"]
    assert any(p["name"] == "escape" and p["owner"] == stored[0].parent.name for p in listing)
    assert request(gateway, "DELETE", f"/api/programs/escape?owner={owner}")[0] == 204


def test_another_sites_page_cannot_change_the_library(gateway):
    """A form on another site can post text/plain and carries that site's Origin: neither a
    write nor a delete from such a request changes the library."""
    assert request(gateway, "PUT", "/api/programs/kept", json.dumps(PROGRAM).encode())[0] == 200
    form = json.dumps({"format": "rosgate-program", "evil": True}).encode()
    status, reply = request(gateway, "POST", "/api/programs/kept", form, content_type="text/plain")
    assert status == 415, reply
    for method, body in (("PUT", json.dumps(PROGRAM).encode()), ("POST", form), ("DELETE", None)):
        req = urllib.request.Request(gateway.http_url.rstrip("/") + "/api/programs/kept", data=body,
                                     method=method, headers={"Origin": "http://evil.example",
                                                             "Content-Type": "application/json"})
        with pytest.raises(urllib.error.HTTPError) as refused:
            urllib.request.urlopen(req, timeout=5)
        assert refused.value.code == 403, method
        assert b"evil.example" in refused.value.read()
    status, body = request(gateway, "GET", "/api/programs/kept")
    assert status == 200 and json.loads(body) == PROGRAM
    own = gateway.http_url.rstrip("/")   # the gateway's own pages may
    req = urllib.request.Request(own + "/api/programs/kept", method="DELETE", headers={"Origin": own})
    with urllib.request.urlopen(req, timeout=5) as res:
        assert res.status == 204
