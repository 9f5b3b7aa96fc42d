"""The HTTP side: Host checked on every route (DNS rebinding), bodies judged by their headers,
only the IDE's public files served, no symlinks followed in the program library."""

from __future__ import annotations

import json
import os
import socket

import pytest

from tests.support.auth import TOKENS
from tests.support.http import http
from tests.support.rawsocket import upgrade_request


def raw_request(gw, head: str) -> str:
    """Send only a request head (no body) and read the status line the server answers with."""
    with socket.create_connection((gw.host, gw.port), timeout=10) as s:
        s.sendall(head.encode())
        data = b''
        while b'\r\n' not in data:
            chunk = s.recv(4096)
            if not chunk:
                break
            data += chunk
    return data.split(b'\r\n', 1)[0].decode()


def upgrade(gw, host: str, origin: str) -> str:
    return raw_request(gw, upgrade_request(host, origin=origin).decode())


@pytest.fixture(scope='module')
def hosts(launch):
    return launch('--allowed-hosts', "['robot.example.org', '*.lab.example']")


def test_dns_rebinding_is_refused_on_every_route(gateway):
    port = gateway.port
    evil = f'evil.example:{port}'
    assert upgrade(gateway, evil, f'http://{evil}').startswith('HTTP/1.1 421')
    for path in ('/', '/health', '/teleop', '/api/programs', '/vendor/roslib.mjs', '/login'):
        assert http(gateway, path, host=evil)[0] == 421, path
    assert http(gateway, '/api/programs/x', host=evil, method='PUT', data=b'{}')[0] == 421
    # names of this machine and IP literals pass
    for host in (f'127.0.0.1:{port}', f'localhost:{port}', f'{socket.gethostname()}:{port}'):
        assert upgrade(gateway, host, f'http://{host}').startswith('HTTP/1.1 101'), host
        assert http(gateway, '/health', host=host)[0] == 200, host


def test_allowed_hosts_globs(hosts):
    for host in ('robot.example.org', 'pi.lab.example:8080'):
        assert http(hosts, '/health', host=host)[0] == 200, host
        assert upgrade(hosts, host, f'http://{host}').startswith('HTTP/1.1 101'), host
    assert http(hosts, '/health', host='robot.example.org.evil.example')[0] == 421


def test_only_what_the_pages_load_is_served(gateway):
    for path in ('/', '/teleop', '/toolbox.json', '/js/ide/main.js', '/vendor/roslib.mjs', '/css/ide.css'):
        assert http(gateway, path)[0] == 200, path
    for path in ('/node_modules/roslib/package.json', '/node_modules/.package-lock.json', '/package.json',
                 '/package-lock.json', '/build.mjs', '/README.md', '/vendor/../node_modules/roslib/package.json'):
        assert http(gateway, path)[0] == 404, path


def test_symlinks_in_the_program_library_are_not_followed(gateway, tmp_path):
    secret = tmp_path / 'secret.json'
    secret.write_text(json.dumps({'secret': 'do not serve'}))
    os.makedirs(gateway.programs_dir, exist_ok=True)   # made by the first save, which may not have happened yet
    link = os.path.join(gateway.programs_dir, 'linked.json')
    os.symlink(secret, link)
    try:
        status, body, _ = http(gateway, '/api/programs/linked')
        assert status == 404 and b'do not serve' not in body
        names = [p['name'] for p in json.loads(http(gateway, '/api/programs')[1])['programs']]
        assert 'linked' not in names
    finally:
        os.unlink(link)


def test_bodies_are_refused_by_their_headers(gateway):
    head = ('PUT /api/programs/big HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n'
            'Content-Length: 40000000\r\n\r\n')
    assert raw_request(gateway, head).startswith('HTTP/1.1 413')   # answered with no byte of the body sent


def test_unauthenticated_bodies_are_refused_before_reading(launch, tokens_file):
    gw = launch('--auth', tokens_file)
    head = ('PUT /api/programs/big HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n'
            'Content-Length: 3000000\r\n\r\n')
    assert raw_request(gw, head).startswith('HTTP/1.1 401')
    bad = head.replace('\r\n\r\n', '\r\nAuthorization: Bearer not-a-token-at-all\r\n\r\n')
    assert raw_request(gw, bad).startswith('HTTP/1.1 401')
    admin = {'Authorization': f"Bearer {TOKENS['admin']}", 'Content-Type': 'application/json'}
    assert http(gw, '/api/programs/ok', method='PUT', data=b'{"blocks": {}}', headers=admin)[0] == 200
    status, *_ = http(gw, '/login', method='POST', data=b'token=wrong&next=/',
                     headers={'Content-Type': 'application/x-www-form-urlencoded'})
    assert status == 401   # the login form itself is a small body read without a token
