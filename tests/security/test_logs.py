"""What the gateway logs: no token value, whatever request carried it, and no line that a name a
client chose (a run's name, a topic) could forge with a newline."""

from __future__ import annotations

from urllib.parse import quote

from tests.support.auth import TOKENS
from tests.support.http import api, http
from tests.support.wait import wait_for
from tests.support.wsclient import Client, with_token

FORGED = '2030-01-01 00:00:00,000 INFO rosgate: FORGED'


def get(gw, path: str) -> int:
    return http(gw, path).status


def test_no_token_value_in_the_log(launch, tokens_file, tmp_path):
    gw = launch('--auth', tokens_file, '--auth-backoff', '0', '--allow-runs', '--runs-dir', str(tmp_path / 'runs'),
                '--log-level', 'debug')
    wrong = 'wrong-token-7f7f7f'
    for token in (*TOKENS.values(), wrong):
        assert get(gw, f'/api/runs/nope?token={token}') in (401, 404, 429)
        assert get(gw, f'/api/programs/bad%20name%21?token={token}') in (400, 401, 429)
        assert get(gw, f'/no/such/page?token={token}') == 404
        assert get(gw, f'/api/recordings/rec-1/play?token={token}') == 405
        with Client(gw.ws_url, token) as c:   # accepted or not, the upgrade's URL carries it
            c.call('/rosapi/get_time')
    # a run's own connection carries its key
    status, body = api(gw, 'POST', '/api/runs', {'source': 'print("hi")'}, TOKENS['operator'])
    assert status == 201, body
    wait_for(lambda: api(gw, 'GET', f"/api/runs/{body['id']}", token=TOKENS['admin'])[1]['state'] != 'running', 30)
    wait_for(lambda: '/api/runs/nope?[query]' in gw.log_text(), 10)
    log = gw.log_text()
    for token in (*TOKENS.values(), wrong):
        assert token not in log
    assert 'run_key=' not in log.replace('run_key=[redacted]', '')


SPELLINGS = ('token', '%74oken', 'to%6Ben', 'TOKEN', '%54%4F%4B%45%4E')   # tornado decodes each name


def test_no_token_in_the_log_however_it_is_spelled(launch, tokens_file):
    """?%74oken= is the token to tornado, and a regex over the word "token" let it through."""
    gw = launch('--auth', tokens_file, '--auth-backoff', '0', '--log-level', 'debug')
    secrets = {}
    for i, name in enumerate(SPELLINGS):
        wrong = secrets[f'wrong-{i}'] = f'wrong-secret-{i}-5e5e5e'
        for token in (TOKENS['viewer'], wrong):
            get(gw, f'/?{name}={token}')                        # a page
            get(gw, f'/teleop?x=1&{name}={token}')              # a page, the token not first
            get(gw, f'/api/runs?{name}={token}')                # an API (no --allow-runs: 404)
            get(gw, f'/api/programs?{name}={token}')            # an API
            get(gw, f'/no/such/page?{name}={token}')            # a missing path
            get(gw, f'/api/no/such?{name}={token}#frag')        # a missing API path
    wait_for(lambda: gw.log_text().count('/no/such/page') >= 2 * len(SPELLINGS), 10)   # all logged
    log = gw.log_text()
    for secret in (TOKENS['viewer'], *secrets.values()):
        assert secret not in log, f'{secret} in the log'
    assert '/no/such/page' in log and '/api/programs' in log   # the paths are there


def test_no_log_line_forged_by_a_name(launch, tokens_file, tmp_path):
    gw = launch('--auth', tokens_file, '--allow-runs', '--runs-dir', str(tmp_path / 'runs'), '--record',
                str(tmp_path / 'rec'), '--record-topics', '/none')
    status, body = api(gw, 'POST', '/api/runs', {'source': 'print(1)', 'name': f'x\n{FORGED} run'},
                       TOKENS['operator'])
    assert status == 201, body
    status, rec = api(gw, 'POST', '/api/recordings', {'topics': [f'/x\r\n{FORGED} topic']}, TOKENS['operator'])
    assert status == 201, rec
    api(gw, 'DELETE', f"/api/recordings/{rec['id']}", token=TOKENS['operator'])
    with Client(with_token(gw.ws_url, TOKENS['operator']) + '&name=' + quote(f'a\n{FORGED}')) as c:
        c.publish(f'/y\n{FORGED} published', {'data': 1}, 'std_msgs/msg/Int32')
        c.sync()
    wait_for(lambda: f'\\n{FORGED} run' in gw.log_text(), 30)          # the run ended, logged with its name
    wait_for(lambda: f'\\r\\n{FORGED} topic' in gw.log_text(), 10)    # the recording, with its globs
    assert not [line for line in gw.log_text().splitlines() if line.startswith(FORGED)]
