"""The camera URLs (/stream, /snapshot, /stream_viewer, /streams) under --auth: the rules of a
subscribe (a token by header or ?token=, or the session cookie of /login; the topic globs) and
no open CORS."""

from __future__ import annotations

from urllib.parse import quote

import pytest

from tests.support.auth import TOKENS, login
from tests.support.camera import BOUNDARY, Stream, stream_head

CAMERA = '/camera/image_raw'


@pytest.fixture(scope='module')
def secured(launch, tokens_file):
    return launch('--auth', tokens_file, '--robot', 'rover')


def status_of(stream: Stream) -> int:
    return int(stream.head.split(b' ')[1])


def test_a_token_is_needed(secured):
    for path in (f'/stream?topic={CAMERA}', f'/snapshot?topic={CAMERA}', f'/stream_viewer?topic={CAMERA}',
                 '/streams'):
        s = Stream(secured.port, path)
        try:
            assert status_of(s) == 401, path
            assert b'Access-Control-Allow-Origin' not in s.head
            assert b'token is required' in s.body()
        finally:
            s.close()
    s = Stream(secured.port, f'/stream?topic={CAMERA}&token=not-a-token')
    try:
        assert status_of(s) == 401
    finally:
        s.close()


@pytest.mark.parametrize('how', ['header', 'cookie', 'query'])
def test_each_way_of_giving_the_token(secured, how):
    token = TOKENS['viewer']
    path, headers = f'/stream?topic={CAMERA}', ''
    if how == 'header':
        headers = f'Authorization: Bearer {token}\r\n'
    elif how == 'cookie':   # the session cookie of /login
        headers = f'Cookie: {login(secured, TOKENS["viewer"])}\r\n'
    else:
        path += f'&token={quote(token)}'
    s = Stream(secured.port, path, headers=headers)
    try:
        assert s.head == stream_head(cors=False)   # web_video_server's bytes without the open CORS
        assert s.opening() == b'--' + BOUNDARY + b'\r\n'
        kind, _, data = s.part()
        assert kind == 'image/jpeg' and data[:2] == b'\xff\xd8'
    finally:
        s.close()


def test_snapshot_has_no_open_cors_under_auth(secured):
    s = Stream(secured.port, f'/snapshot?topic={CAMERA}', headers=f'Authorization: Bearer {TOKENS["admin"]}\r\n')
    try:
        body = s.body()
    finally:
        s.close()
    assert s.head.startswith(b'HTTP/1.0 200 OK\r\n') and b'Access-Control-Allow-Origin' not in s.head
    assert body[:2] == b'\xff\xd8'


def test_topic_globs_apply(launch, tokens_file):
    gw = launch('--auth', tokens_file, '--robot', 'rover', '--topics-glob', "['/odom', '/scan']")
    auth = f'Authorization: Bearer {TOKENS["admin"]}\r\n'
    for path in (f'/stream?topic={CAMERA}', f'/snapshot?topic={CAMERA}', f'/stream?topic={CAMERA}/compressed'):
        s = Stream(gw.port, path, headers=auth)
        try:
            assert status_of(s) == 403, path
            assert b'not allowed for subscribe' in s.body()
        finally:
            s.close()
    s = Stream(gw.port, '/streams', headers=auth)
    try:
        assert status_of(s) == 200 and CAMERA.encode() not in s.body()
    finally:
        s.close()
