"""GET /package/PKG/PATH and /urdf: a description package's files from AMENT_PREFIX_PATH's share
folders and --mesh-path, with caching headers; every way out of those roots refused; a token
needed under --auth."""

from __future__ import annotations

import http.client
import os

import pytest

from tests.support.auth import TOKENS

STL = b'solid body\nendsolid body\n'
SECRET = b'TOP-SECRET-42'


@pytest.fixture(scope='module')
def roots(tmp_path_factory):
    """A prefix (AMENT_PREFIX_PATH) with share/prefixbot, a mesh folder with testbot, a secret
    beside them, and a symlink inside testbot pointing at the secret."""
    top = tmp_path_factory.mktemp('packages')
    (top / 'secret.stl').write_bytes(SECRET)
    (top / 'secret.txt').write_bytes(SECRET)
    meshes = top / 'meshes' / 'testbot' / 'meshes'
    meshes.mkdir(parents=True)
    (meshes / 'body.stl').write_bytes(STL)
    (meshes / 'run.py').write_bytes(SECRET)
    os.symlink(top / 'secret.stl', meshes / 'link.stl')
    hidden = top / 'meshes' / 'testbot' / '.hidden'
    hidden.mkdir()
    (hidden / 'key.stl').write_bytes(SECRET)
    share = top / 'prefix' / 'share' / 'prefixbot' / 'urdf'
    share.mkdir(parents=True)
    (share / 'bot.urdf').write_text('<robot name="prefixbot"/>')
    (top / 'robot.urdf').write_text('<robot name="from-file"/>')
    return top


def get(gw, path: str, headers: dict | None = None) -> tuple[int, dict, bytes]:
    """A request sent as written (http.client neither normalises nor re-encodes the path)."""
    conn = http.client.HTTPConnection('127.0.0.1', gw.port, timeout=10)
    try:
        conn.putrequest('GET', path, skip_accept_encoding=True)
        for k, v in (headers or {}).items():
            conn.putheader(k, v)
        conn.endheaders()
        r = conn.getresponse()
        return r.status, dict(r.getheaders()), r.read()
    finally:
        conn.close()


@pytest.fixture(scope='module')
def served(launch, roots):
    return launch('--robot', 'none', '--mesh-path', str(roots / 'meshes'), '--urdf', str(roots / 'robot.urdf'),
                  env={'AMENT_PREFIX_PATH': str(roots / 'prefix')})


def test_package_files_are_served_with_caching_headers(served):
    status, headers, body = get(served, '/package/testbot/meshes/body.stl')
    assert status == 200 and body == STL
    assert headers.get('Etag') and headers.get('Last-Modified'), headers
    assert 'max-age=' in headers['Cache-Control']
    status, _, body = get(served, '/package/testbot/meshes/body.stl', {'If-None-Match': headers['Etag']})
    assert status == 304 and body == b''
    status, headers, body = get(served, '/package/prefixbot/urdf/bot.urdf')   # from AMENT_PREFIX_PATH
    assert status == 200 and body == b'<robot name="prefixbot"/>' and headers['Content-Type'].startswith('text/xml')
    status, _, body = get(served, '/urdf')
    assert status == 200 and body == b'<robot name="from-file"/>'
    assert get(served, '/package/testbot/meshes/missing.stl')[0] == 404
    assert get(served, '/package/nobot/meshes/body.stl')[0] == 404


ESCAPES = [
    '/package/testbot/../secret.stl',                          # .. as written
    '/package/testbot/meshes/../../secret.stl',
    '/package/testbot/meshes/%2e%2e/%2e%2e/%2e%2e/secret.stl',  # encoded dots
    '/package/testbot/meshes/..%2f..%2f..%2fsecret.stl',       # encoded slashes
    '/package/testbot/%2Fetc%2Fpasswd',                        # absolute (encoded)
    '/package/testbot//etc/passwd',                            # absolute (empty segment)
    '/package/%2e%2e/secret.stl',                              # the package itself is ..
    '/package/..%2fsecret.stl/x.stl',
    '/package/testbot/meshes/link.stl',                        # a symlink pointing out
    '/package/testbot/meshes/body.stl%00.png',                 # NUL byte
    '/package/testbot/meshes/..%5c..%5c..%5csecret.stl',       # backslashes
    '/package/testbot/.hidden/key.stl',                        # a hidden folder
    '/package/testbot/meshes/run.py',                          # not a mesh, texture or description
    '/package/testbot/meshes/%252e%252e/%252e%252e/secret.stl',  # double-encoded: a name, not a way out
    '/package/testbot/meshes/./body.stl',
    '/package/testbot/meshes/%20../secret.stl',
]


@pytest.mark.parametrize('path', ESCAPES)
def test_escapes_are_refused(served, path):
    status, _, body = get(served, path)
    assert status in (403, 404), (path, status)
    assert SECRET not in body


def test_a_token_is_needed_under_auth(launch, roots, tokens_file):
    gw = launch('--auth', tokens_file, '--robot', 'none', '--mesh-path', str(roots / 'meshes'))
    assert get(gw, '/package/testbot/meshes/body.stl')[0] == 401
    assert get(gw, '/urdf')[0] == 401
    status, _, body = get(gw, '/package/testbot/meshes/body.stl', {'Authorization': f'Bearer {TOKENS["viewer"]}'})
    assert status == 200 and body == STL
    assert get(gw, '/urdf', {'Authorization': f'Bearer {TOKENS["viewer"]}'})[0] == 404   # no --urdf here
