"""The token file, rosauth MACs and the brake on guessing, as plain function calls."""

from __future__ import annotations

import hashlib

import pytest

from gateway.auth.tokens import Authenticator, AuthError, Brake, Identity, TokenStore


def store_from(tmp_path, text: str) -> TokenStore:
    path = tmp_path / 'tokens.toml'
    path.write_text(text)
    return TokenStore.load(path)


def test_plain_and_hashed_tokens(tmp_path):
    digest = hashlib.sha256(b'hashed-token-42').hexdigest()
    store = store_from(tmp_path, f'''
[[tokens]]
name = "a"
role = "operator"
token = "plain-token-17"
[[tokens]]
role = "admin"
sha256 = "{digest}"
''')
    assert store.check_token('plain-token-17') == Identity('a', 'operator')
    assert store.check_token('hashed-token-42') == Identity('admin2', 'admin')
    assert store.check_token('plain-token-1') is None and store.check_token('') is None


@pytest.mark.parametrize('text, error', [
    ('', 'nobody could connect'),
    ('[[tokens]]\nrole = "root"\ntoken = "abcdefghij"\n', 'role must be one of'),
    ('[[tokens]]\nrole = "admin"\ntoken = "short"\n', '8 or more'),
    ('[[tokens]]\nrole = "admin"\ntoken = "has space in it"\n', '8 or more'),
    ('[[tokens]]\nrole = "admin"\nsha256 = "abc"\n', '64 hex digits'),
    ('[[tokens]]\nrole = "admin"\n', 'give token or sha256'),
    ('[rosauth]\nrole = "admin"\n', 'needs a secret'),
])
def test_bad_token_files_are_refused(tmp_path, text, error):
    with pytest.raises(ValueError, match=error):
        store_from(tmp_path, text)


def test_rosauth_window_expiry_and_replay(tmp_path):
    store = store_from(tmp_path, '[rosauth]\nsecret = "s3cret"\nallowed_time_delta = 5\n')
    ra = store.rosauth

    def check(t, end, level='admin', now=1000.0, mac=None):
        mac = mac or ra.mac('c', 'd', 'r', t, level, end)
        return store.check_rosauth(mac, 'c', 'd', 'r', {'secs': t, 'nsecs': 0}, level, {'sec': end}, now=now)

    assert check(998, 1100) == Identity('c', 'admin')
    assert check(998, 1100) is None                     # the same MAC again is a replay
    assert check(990, 1100) is None                     # t too far from now
    assert check(1000, 999) is None                     # already ended
    assert check(1000, 1100, mac='0' * 128) is None     # wrong MAC
    assert check(1001, 1100, level='user') == Identity('c', 'operator')   # not a role: the default


def test_brake_doubles_the_wait_after_free_attempts():
    now = [0.0]
    brake = Brake(free=3, base=0.5, cap=4.0, clock=lambda: now[0])
    for _ in range(3):
        assert brake.retry_after('ip') == 0
        brake.failed('ip')
    waits = []
    for _ in range(5):
        wait = brake.retry_after('ip')
        waits.append(wait)
        now[0] += wait
        brake.failed('ip')
    assert waits == [0.5, 1.0, 2.0, 4.0, 4.0]
    assert brake.retry_after('other') == 0


def test_authenticator_refuses_unchecked_during_the_wait(tmp_path):
    store = store_from(tmp_path, '[[tokens]]\nrole = "viewer"\ntoken = "good-token-1"\n')
    now = [0.0]
    auth = Authenticator(store, Brake(free=1, base=10, clock=lambda: now[0]))
    with pytest.raises(AuthError, match='invalid token'):
        auth.token('ip', 'bad-token-1')
    with pytest.raises(AuthError, match='retry in 10.0 s'):
        auth.token('ip', 'good-token-1')
    now[0] = 10.0
    assert auth.token('ip', 'good-token-1').role == 'viewer'
