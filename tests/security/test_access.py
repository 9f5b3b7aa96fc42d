"""Access control over real websockets: origins, tokens and roles, the login page, rosauth."""

from __future__ import annotations

import hashlib
import json
import math
import time
import urllib.error
import urllib.parse
import urllib.request

import pytest
from websockets.exceptions import InvalidStatus

from tests.support.auth import ROSAUTH_SECRET, TOKENS, login
from tests.support.http import http
from tests.support.wait import wait_for
from tests.support.wsclient import Client

ROLES = ('viewer', 'operator', 'admin')


@pytest.fixture(scope='module')
def secured(launch, tokens_file):
    return launch('--auth', tokens_file, '--fibonacci-interval', '0.01')


def connect(gw, role: str, how: str = 'query') -> Client:
    """A client of the given role; the token travels as a query parameter, a header or an auth op."""
    token = TOKENS[role]
    if how == 'query':
        return Client(gw.ws_url, token)
    if how == 'header':
        return Client(gw.ws_url, additional_headers={'Authorization': f'Bearer {token}'})
    client = Client(gw.ws_url)
    client.send({'op': 'auth', 'token': token, 'id': 'auth'})
    assert client.call('/rosapi/get_time')['result'] is True
    return client


# --- origins ---------------------------------------------------------------------------------

def test_foreign_origin_refused_with_403(gateway):
    """An origin is scheme, host and port: the gateway's own passes (localhost and its addresses
    standing for each other on that port); another port or scheme of the same machine does not."""
    port = gateway.port
    for origin in ('http://evil.example.com', f'http://127.0.0.1:{port + 1}', 'http://localhost:8000',
                   'http://127.0.0.1', 'null'):
        with pytest.raises(InvalidStatus) as info:
            Client(gateway.ws_url, origin=origin)
        assert info.value.response.status_code == 403, origin
    for origin in (f'http://127.0.0.1:{port}', f'http://localhost:{port}', f'http://[::1]:{port}'):
        with Client(gateway.ws_url, origin=origin) as ok:
            assert ok.call('/rosapi/get_time')['result'] is True


def test_websocket_takes_the_browsers_same_origin_as_http_does(gateway):
    """Behind a TLS proxy the page is https://lab:8443 while the gateway sees http on its own port:
    a browser's Sec-Fetch-Site: same-origin passes the websocket's check as it passes the HTTP
    routes'; the same Origin from another site (or the browser saying so) is refused."""
    origin = f'https://localhost:{gateway.port + 1}'
    with Client(gateway.ws_url, origin=origin, additional_headers={'Sec-Fetch-Site': 'same-origin'}) as ok:
        assert ok.call('/rosapi/get_time')['result'] is True
    for site in ('same-site', 'cross-site', None):
        headers = {'Sec-Fetch-Site': site} if site else {}
        with pytest.raises(InvalidStatus) as info:
            Client(gateway.ws_url, origin=origin, additional_headers=headers)
        assert info.value.response.status_code == 403, site


def test_state_changing_requests_check_where_they_come_from_whatever_the_body(gateway):
    """The same rule for every route that changes something, login included, empty bodies too:
    Origin another port of this host, or a browser's word that it is another site, is refused
    before anything happens; the browser's own same-origin (as behind a TLS proxy, where the
    Origin's scheme and port are not what the gateway sees) and clients without a browser pass."""
    port = gateway.port
    elsewhere = {'Origin': f'http://127.0.0.1:{port + 1}', 'Sec-Fetch-Site': 'same-site'}
    no_origin = {'Sec-Fetch-Site': 'cross-site'}
    proxied = {'Origin': 'https://robot.example.org', 'Sec-Fetch-Site': 'same-origin'}
    json_body = {'Content-Type': 'application/json'}
    for headers in (elsewhere, no_origin):
        assert http(gateway, '/api/programs/kept2', method='PUT', data=b'{}', headers={**headers, **json_body})[0] == 403
        assert http(gateway, '/api/recordings/rec-20260101-000000-abcd/play', method='POST', data=b'',
                    headers=headers)[0] == 403   # refused before it is looked up
        assert http(gateway, '/api/runs/r00000000', method='DELETE', headers=headers)[0] == 403
        assert http(gateway, '/login', method='POST', data=b'token=x', headers=headers)[0] == 403
    assert http(gateway, '/api/programs/kept2', method='PUT', data=b'{}', headers={**proxied, **json_body})[0] == 200
    assert http(gateway, '/api/programs/kept2', method='DELETE')[0] == 204
    assert http(gateway, '/api/recordings/rec-20260101-000000-abcd/play', method='POST', data=b'',
                headers={'Origin': f'http://localhost:{port}'})[0] == 404


# --- roles -------------------------------------------------------------------------------------

def _subscribe(c: Client, role: str) -> bool:
    return c.refusal({'op': 'subscribe', 'topic': '/sec/news', 'type': 'std_msgs/msg/String'}) is None


def _read_rosapi(c: Client, role: str) -> bool:
    return c.call('/rosapi/topics')['result']


def _publish(c: Client, role: str) -> bool:
    topic = f'/sec/pub_{role}'
    c.subscribe(topic, 'std_msgs/msg/String')
    c.publish(topic, {'data': role}, 'std_msgs/msg/String', id='pub')
    got = c.expect(lambda m: (m.get('op') == 'publish' and m['topic'] == topic)
                   or (m.get('op') == 'status' and m.get('id') == 'pub'))
    if got['op'] == 'status':
        assert got['msg'].startswith('publish (id pub): ') and f'role {role} may not publish' in got['msg']
        return False
    return True


def _call_service(c: Client, role: str) -> bool:
    reply = c.call('/add_two_ints', {'a': 2, 'b': 3})
    if reply['result']:
        return reply['values'] == {'sum': 5}
    assert 'may not call /add_two_ints' in reply['values']
    return False


def _send_goal(c: Client, role: str) -> bool:
    c.send({'op': 'send_action_goal', 'action': '/fibonacci', 'action_type': 'example_interfaces/action/Fibonacci',
            'args': {'order': 3}, 'id': 'goal'})
    result = c.expect(lambda m: m.get('op') == 'action_result' and m.get('id') == 'goal')
    if result['result']:
        return result['values'] == {'sequence': [0, 1, 1, 2]}
    c.status('goal')   # the refusal is also a status naming op and id
    return False


def _set_param(c: Client, role: str) -> bool:
    reply = c.call('/rosapi/set_param', {'name': '/fibonacci_action_server:step_interval', 'value': '0.01'})
    return reply['result'] and reply['values']['successful']


def _advertise_service(c: Client, role: str) -> bool:
    name = f'/sec/svc_{role}'
    if c.refusal({'op': 'advertise_service', 'service': name, 'type': 'std_srvs/srv/Trigger'}) is not None:
        return False
    return name in c.call('/rosapi/services')['values']['services']


def _advertise_action(c: Client, role: str) -> bool:
    name = f'/sec/act_{role}'
    if c.refusal({'op': 'advertise_action', 'action': name, 'type': 'example_interfaces/action/Fibonacci'}):
        return False
    return name in c.call('/rosapi/action_servers')['values']['action_servers']


CASES = {   # what a role may do: exactly the roles listed
    _subscribe: ROLES,
    _read_rosapi: ROLES,
    _publish: ('operator', 'admin'),
    _call_service: ('operator', 'admin'),
    _send_goal: ('operator', 'admin'),
    _set_param: ('admin',),
    _advertise_service: ('admin',),
    _advertise_action: ('admin',),
}


@pytest.mark.parametrize('role, how', [('viewer', 'auth-op'), ('operator', 'header'), ('admin', 'query')])
def test_each_role_allowed_and_refused_exactly(secured, role, how):
    with connect(secured, role, how) as c:
        outcome = {case.__name__.lstrip('_'): case(c, role) for case in CASES}
    expected = {case.__name__.lstrip('_'): role in roles for case, roles in CASES.items()}
    assert outcome == expected


def test_program_library_keeps_a_space_per_name(secured):
    def as_(role, path, method='GET', data=None):
        headers = {'Authorization': f'Bearer {TOKENS[role]}', 'Content-Type': 'application/json'}
        status, body, _ = http(secured, path, method=method, data=data, headers=headers)
        return status, json.loads(body) if body else None

    def names(role, query=''):
        status, body = as_(role, '/api/programs' + query)
        assert status == 200, body
        return sorted(((p['owner'], p['name']) for p in body['programs']), key=lambda p: (p[0] or '', p[1]))

    assert http(secured, '/api/programs')[0] == 401
    assert as_('viewer', '/api/programs')[0] == 200
    # operators save without the teacher's token, each in a space of their own
    assert as_('operator', '/api/programs/square', 'PUT', b'{"who": "alice"}')[0] == 200
    assert as_('operator2', '/api/programs/square', 'PUT', b'{"who": "bob"}')[0] == 200
    assert as_('admin', '/api/programs/starter', 'PUT', b'{"who": "teacher"}')[0] == 200
    assert as_('operator', '/api/programs/square')[1] == {'who': 'alice'}
    assert as_('operator2', '/api/programs/square')[1] == {'who': 'bob'}
    assert names('operator') == [('alice', 'square')]
    assert names('operator2') == [('bob', 'square')]
    # nobody else's space, by name or by ?owner=
    assert as_('operator', '/api/programs/square?owner=bob')[0] == 403
    assert as_('operator', '/api/programs/starter')[0] == 404
    assert [p['owner'] for p in as_('operator', '/api/programs?owner=bob')[1]['programs']] == ['alice']
    # a viewer reads its own space and saves nothing
    status, body = as_('viewer', '/api/programs/mine', 'PUT', b'{}')
    assert status == 403 and 'viewer' in body['error']
    # the admin sees every space and opens, saves and deletes in any of them
    assert names('admin') == [(None, 'starter'), ('alice', 'square'), ('bob', 'square')]
    assert as_('admin', '/api/programs/square?owner=bob')[1] == {'who': 'bob'}
    assert as_('admin', '/api/programs/square?owner=alice', 'DELETE')[0] == 204
    assert names('operator') == []
    assert as_('operator', '/api/programs/square', 'DELETE')[0] == 404


def test_before_auth_only_auth_is_accepted(secured):
    with Client(secured.ws_url) as c:
        refused = c.refusal({'op': 'subscribe', 'topic': '/sec/news', 'type': 'std_msgs/msg/String', 'id': 's1'})
        assert refused['msg'].startswith('subscribe (id s1): not authenticated')
        reply = c.call('/rosapi/get_time')
        assert reply['result'] is False and 'not authenticated' in reply['values']
        c.send({'op': 'auth', 'token': 'not-a-token-at-all', 'id': 'a1'})
        assert c.status('a1')['msg'] == 'auth (id a1): invalid token'
        c.send({'op': 'auth', 'token': TOKENS['viewer'], 'id': 'a2'})
        assert c.call('/rosapi/get_time')['result'] is True


def test_login_page_sets_the_cookie_the_websocket_accepts(secured):
    status, body, _ = http(secured, '/login')
    assert status == 200 and b'<form method="post" action="/login">' in body
    form = urllib.parse.urlencode({'token': TOKENS['admin'], 'next': '/?x=1'}).encode()
    status, _, headers = http(secured, '/login', method='POST', data=form)
    assert status == 303 and headers['Location'] == '/?x=1'
    cookie = headers['Set-Cookie']
    assert 'httponly' in cookie.lower() and 'samesite=lax' in cookie.lower()
    assert 'secure' not in cookie.lower()        # plain http: a Secure cookie would not come back
    pair = cookie.split(';', 1)[0]
    with Client(secured.ws_url, additional_headers={'Cookie': pair}) as c:
        assert _set_param(c, 'admin')
    assert http(secured, '/api/programs', headers={'Cookie': pair})[0] == 200
    status, body, _ = http(secured, '/whoami', headers={'Cookie': pair})
    assert status == 200 and json.loads(body) == {'auth': True, 'name': 'teacher', 'role': 'admin'}
    assert http(secured, '/whoami')[0] == 401


def test_the_cookie_is_not_the_token(secured):
    """The session cookie holds a signed random id: neither the token nor anything made from it,
    a new one at each sign-in; its value with a changed signature, or as a token, is no one."""
    pair = login(secured, TOKENS['admin'])
    name, value = pair.split('=', 1)
    assert name == 'rosgate_session'
    token = TOKENS['admin']
    for form in (token, urllib.parse.quote(token), hashlib.sha256(token.encode()).hexdigest(),
                 __import__('base64').b64encode(token.encode()).decode().rstrip('=')):
        assert form not in urllib.parse.unquote(value)
    assert login(secured, TOKENS['admin']) != pair
    forged = value[:-4] + ('0000' if not value.endswith('0000') else '1111')
    assert http(secured, '/whoami', headers={'Cookie': f'{name}={forged}'})[0] == 401
    assert http(secured, '/whoami', headers={'Cookie': f'rosgate_token={token}'})[0] == 401
    assert http(secured, '/whoami', headers={'Authorization': f'Bearer {value}'})[0] == 401


def test_logout_ends_the_session_on_the_server(secured):
    """A copy of the cookie (another browser, a stolen one) stops working once its owner signs out."""
    pair = login(secured, TOKENS['operator'])
    copy = pair
    assert http(secured, '/whoami', headers={'Cookie': copy})[0] == 200
    status, _, headers = http(secured, '/logout', method='POST', headers={'Cookie': pair})
    assert status == 303 and 'max-age=0' in headers['Set-Cookie'].lower()
    assert http(secured, '/whoami', headers={'Cookie': copy})[0] == 401
    with Client(secured.ws_url, additional_headers={'Cookie': copy}) as c:
        reply = c.call('/rosapi/get_time')
        assert reply['result'] is False and 'not authenticated' in reply['values']


def test_logout_closes_that_sign_ins_websockets_and_no_others(secured):
    """Her pages' websockets close (1008) the moment she signs out (``auth.sessions`` tells the
    hooks, ``bridge.doors.SignOuts`` closes them); another sign-in's connection carries on."""
    mine, other = login(secured, TOKENS['operator']), login(secured, TOKENS['operator'])
    with Client(secured.ws_url, additional_headers={'Cookie': mine}) as hers, \
            Client(secured.ws_url, additional_headers={'Cookie': other}) as theirs:
        assert hers.call('/rosapi/get_time')['result'] is True
        assert http(secured, '/logout', method='POST', headers={'Cookie': mine})[0] == 303
        assert hers.closed_code(30) == 1008
        assert theirs.call('/rosapi/get_time')['result'] is True


def test_sessions_survive_a_restart_and_end_at_their_expiry(launch, tokens_file, tmp_path):
    """Kept in the store: a restarted gateway knows its sessions; --session-hours bounds them."""
    from tests.support.process import GatewayProcess
    home = str(tmp_path / 'home')
    gw = GatewayProcess('--auth', tokens_file, env={'XDG_DATA_HOME': home})
    try:
        pair = login(gw, TOKENS['viewer'])
        ended = login(gw, TOKENS['operator'])
        assert http(gw, '/logout', method='POST', headers={'Cookie': ended})[0] == 303
    finally:
        gw.stop()
    gw = GatewayProcess('--auth', tokens_file, env={'XDG_DATA_HOME': home})
    try:
        status, body, _ = http(gw, '/whoami', headers={'Cookie': pair})
        assert status == 200 and json.loads(body)['role'] == 'viewer'
        assert http(gw, '/whoami', headers={'Cookie': ended})[0] == 401
    finally:
        gw.stop()
    gw = GatewayProcess('--auth', tokens_file, '--session-hours', '0.001', env={'XDG_DATA_HOME': home})
    try:
        short = login(gw, TOKENS['viewer'])
        assert http(gw, '/whoami', headers={'Cookie': short})[0] == 200
        wait_for(lambda: http(gw, '/whoami', headers={'Cookie': short})[0] == 401, timeout=20)   # past its 3.6 s lifetime
    finally:
        gw.stop()


def rosauth_op(client: str, level: str, t: int, secret: str = ROSAUTH_SECRET) -> dict:
    dest, rand, end = '127.0.0.1', 'r4nd0m', t + 60
    mac = hashlib.sha512(f'{secret}{client}{dest}{rand}{t}{level}{end}'.encode()).hexdigest()
    return {'op': 'auth', 'mac': mac, 'client': client, 'dest': dest, 'rand': rand,
            't': {'secs': t, 'nsecs': 0}, 'level': level, 'end': {'secs': end, 'nsecs': 0}}


def test_rosauth_mac_accepted_once(secured):
    op = rosauth_op('10.0.0.7', 'operator', int(time.time()))
    with Client(secured.ws_url) as c:
        c.send({**op, 'id': 'ra'})
        assert _call_service(c, 'operator')
    with Client(secured.ws_url) as replay:
        replay.send({**op, 'id': 'ra'})
        assert replay.status('ra')['msg'] == 'auth (id ra): invalid rosauth MAC'


# --- brute force -----------------------------------------------------------------------------

def test_brute_force_is_slowed(launch, tokens_file):
    gw = launch('--auth', tokens_file)
    verdicts = {'invalid token': 0, 'too many failed attempts': 0}
    with Client(gw.ws_url) as attacker:
        start = time.monotonic()
        n = 0
        while n < 50:   # as fast as this machine sends them
            n += 1
            attacker.send({'op': 'auth', 'token': f'guess-{n:06d}', 'id': f'g{n}'})
            msg = attacker.status(f'g{n}')['msg']
            verdicts[next(v for v in verdicts if v in msg)] += 1
        elapsed = time.monotonic() - start
        # during the lockout even the right token is refused unchecked, from any connection
        attacker.send({'op': 'auth', 'token': TOKENS['admin'], 'id': 'right'})
        assert 'too many failed attempts' in attacker.status('right')['msg']
        with Client(gw.ws_url, TOKENS['admin']) as other:
            assert 'too many failed attempts' in other.call('/rosapi/get_time')['values']
        assert http(gw, '/login', method='POST', data=b'token=whatever')[0] == 429
    checked = verdicts['invalid token']
    print(f'\nbrute force: {n} guesses in {elapsed:.2f} s, {checked} checked '
          f'({checked / elapsed:.1f}/s), {n - checked} refused unchecked')
    # the brake's law (3 free, then waits of 0.5, 1, 2 ... s): in t seconds at most 3 + log2(2t + 1)
    # guesses are checked, however fast they come (50 in 2 s on an idle machine: 6 checked)
    assert checked <= 3 + math.floor(math.log2(2 * elapsed + 1)) + 1, (checked, elapsed)
    # the lockout ends: the right token gets through again
    deadline = time.monotonic() + 10

    def admitted() -> bool:
        with Client(gw.ws_url, TOKENS['viewer']) as c:
            return c.call('/rosapi/get_time')['result']

    while not admitted():
        assert time.monotonic() < deadline, 'the lockout did not end'
        time.sleep(0.1)


# --- TLS ---------------------------------------------------------------------------------------

def test_wss_with_self_signed_certificate(launch, tokens_file, certificate):
    import ssl
    cert, key = certificate
    gw = launch('--certfile', cert, '--keyfile', key, '--auth', tokens_file)
    assert gw.ws_url.startswith('wss://127.0.0.1:')
    ctx = ssl.create_default_context(cafile=cert)
    with Client(gw.ws_url, TOKENS['operator'], ssl=ctx) as c:
        assert _call_service(c, 'operator')
        assert not _set_param(c, 'operator')
    with pytest.raises(Exception):
        Client(gw.ws_url.replace('wss://', 'ws://'), TOKENS['operator'])
    form = urllib.parse.urlencode({'token': TOKENS['viewer']}).encode()
    request = urllib.request.Request(gw.http_url + 'login', data=form, method='POST')

    class NoRedirect(urllib.request.HTTPRedirectHandler):
        def redirect_request(self, *args, **kw):
            return None
    opener = urllib.request.build_opener(urllib.request.HTTPSHandler(context=ctx), NoRedirect)
    with pytest.raises(urllib.error.HTTPError) as info:
        opener.open(request, timeout=5)
    assert info.value.code == 303
    assert '; secure' in info.value.headers['Set-Cookie'].lower()


def test_the_class_page_goes_out_only_through_its_admin_check(secured):
    """/class sends the signed-out to sign in; its file is not served as a public file."""
    status, _, headers = http(secured, '/class')
    assert status == 302 and headers['Location'].startswith('/login'), (status, dict(headers))
    assert http(secured, '/class.html')[0] == 404
    assert http(secured, '/class.html', headers={'Authorization': f'Bearer {TOKENS["operator"]}'})[0] == 404
    assert http(secured, '/teleop.html')[0] == 200     # the public pages still are
