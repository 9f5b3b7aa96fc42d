"""A small LTI 1.3 platform for tests, on PyJWT: what an LMS does in a launch, through the browser.

It serves its JWKS, starts a launch with an auto-posted form to the tool's OIDC login
initiation, answers the authorization request with an auto-posted, RS256-signed id_token, and
takes deep linking responses back (checked against the tool's published JWKS by the test).
A launch is a dict (``Platform.add``): who (sub, name, roles), target_link_uri, custom, message
type, and ``forge``: what to get wrong on purpose (``key``: signed with a key the platform does
not publish under that kid; ``aud``; ``expired``; ``deployment``; ``type``: a message type the tool does not take; ``version``; ``state``: another state than
the tool gave; ``replay:N``: the N-th id_token posted before, with the state of this new
login). Every id_token it posted is kept (``posted``) so a test can post one again.
"""

from __future__ import annotations

import asyncio
import html
import itertools
import json
import threading
import time
import uuid

import jwt
import tornado.web
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric import rsa

CLAIM = 'https://purl.imsglobal.org/spec/lti/claim/'
DL = 'https://purl.imsglobal.org/spec/lti-dl/claim/'
LEARNER = 'http://purl.imsglobal.org/vocab/lis/v2/membership#Learner'
INSTRUCTOR = 'http://purl.imsglobal.org/vocab/lis/v2/membership#Instructor'
STUDENT = 'http://purl.imsglobal.org/vocab/lis/v2/institution/person#Student'
INST_ADMIN = 'http://purl.imsglobal.org/vocab/lis/v2/institution/person#Administrator'


def form_page(action: str, fields: dict) -> str:
    inputs = ''.join(f'<input type="hidden" name="{html.escape(k)}" value="{html.escape(str(v))}">'
                     for k, v in fields.items())
    return (f'<!doctype html><html><body><form id="f" method="post" action="{html.escape(action)}">{inputs}'
            '<button>go</button></form><script>document.getElementById("f").submit()</script></body></html>')


def write_tool_key(path) -> None:
    """The tool's private key (PEM) at ``path``, as a school's tool configuration names it."""
    key = rsa.generate_private_key(public_exponent=65537, key_size=2048)
    path.write_bytes(key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                                       serialization.NoEncryption()))


class Served:
    """A tornado app on a loopback port, on an event loop of its own in a thread (beside the test's)."""

    def __init__(self, routes: list, kwargs: dict):
        self.loop = asyncio.new_event_loop()
        ready = threading.Event()
        self.thread = threading.Thread(target=self._run, args=([(p, h, kwargs) for p, h in routes], ready),
                                       daemon=True)
        self.thread.start()
        ready.wait(10)

    def _run(self, routes, ready) -> None:
        asyncio.set_event_loop(self.loop)
        server = tornado.web.Application(routes).listen(0, '127.0.0.1')
        self.port = next(iter(server._sockets.values())).getsockname()[1]
        ready.set()
        self.loop.run_forever()

    def stop(self) -> None:
        self.loop.call_soon_threadsafe(self.loop.stop)
        self.thread.join(5)


class Platform:
    def __init__(self, tool: str, client_id: str = 'rosgate-client', deployment: str = 'dep-1'):
        self.tool, self.client_id, self.deployment = tool.rstrip('/'), client_id, deployment
        self.key = rsa.generate_private_key(public_exponent=65537, key_size=2048)
        self.other_key = rsa.generate_private_key(public_exponent=65537, key_size=2048)
        self.kid = 'platform-key-1'
        self.launches: dict[str, dict] = {}
        self.posted: list[dict] = []          # {'id_token', 'state', 'launch'} as posted to the tool
        self.returned: list[str] = []         # deep linking response JWTs the tool posted back
        self.ids = itertools.count(1)
        self.served = Served([(r'/jwks', Jwks), (r'/start', Start), (r'/auth', Auth), (r'/dl-return', DlReturn),
                              (r'/post', Repost), (r'/course', Course)], {'p': self})
        self.issuer = f'http://127.0.0.1:{self.served.port}'

    def stop(self) -> None:
        self.served.stop()

    def rotate(self) -> None:
        """A new signing key under a new kid, published at once (the old one is gone)."""
        self.key = rsa.generate_private_key(public_exponent=65537, key_size=2048)
        self.kid = f'platform-key-{next(self.ids)}'

    def tool_config(self, private_key_file: str) -> dict:
        """This platform's registration in PyLTI1p3's tool configuration format (with a second,
        unrelated platform beside it, as a school's file would have)."""
        return {
            self.issuer: [{'default': True, 'client_id': self.client_id, 'auth_login_url': f'{self.issuer}/auth',
                           'auth_token_url': f'{self.issuer}/token', 'auth_audience': None,
                           'key_set_url': f'{self.issuer}/jwks', 'key_set': None,
                           'private_key_file': private_key_file, 'deployment_ids': [self.deployment]}],
            'https://canvas.example.edu': {'client_id': '10000000000001', 'auth_login_url':
                                           'https://canvas.example.edu/api/lti/authorize_redirect',
                                           'key_set_url': 'https://canvas.example.edu/api/lti/security/jwks',
                                           'private_key_file': private_key_file, 'deployment_ids': ['1:abc']},
        }

    def add(self, sub: str, roles: list[str], *, name: str = '', target: str = '/', custom: dict | None = None,
            kind: str = 'LtiResourceLinkRequest', forge: str = '', locale: str = '') -> str:
        """A launch; returns the URL that starts it in a browser."""
        lid = f'launch-{next(self.ids)}'
        self.launches[lid] = dict(sub=sub, roles=roles, name=name or sub, target=self.tool + target,
                                  custom=custom or {}, kind=kind, forge=forge, locale=locale)
        return f'{self.issuer}/start?launch={lid}'

    def id_token(self, launch: dict, nonce: str) -> str:
        now = int(time.time())
        claims = {
            'iss': self.issuer, 'aud': 'someone-else' if launch['forge'] == 'aud' else self.client_id,
            'sub': launch['sub'], 'name': launch['name'], 'nonce': nonce,
            'iat': now - 7200 if launch['forge'] == 'expired' else now,
            'exp': now - 3600 if launch['forge'] == 'expired' else now + 300,
            CLAIM + 'message_type': 'LtiSubmissionReviewRequest' if launch['forge'] == 'type' else launch['kind'],
            CLAIM + 'version': '1.1' if launch['forge'] == 'version' else '1.3.0',
            CLAIM + 'deployment_id': 'dep-unknown' if launch['forge'] == 'deployment' else self.deployment,
            CLAIM + 'target_link_uri': launch['target'], CLAIM + 'roles': launch['roles'],
            CLAIM + 'context': {'id': 'course-1', 'title': 'Robotics 101'},
        }
        if launch['custom']:
            claims[CLAIM + 'custom'] = launch['custom']
        if launch['locale']:     # the course's language
            claims[CLAIM + 'launch_presentation'] = {'locale': launch['locale'], 'document_target': 'window'}
        if launch['kind'] == 'LtiResourceLinkRequest':
            claims[CLAIM + 'resource_link'] = {'id': 'link-1', 'title': 'Robot lab'}
        else:
            claims[DL + 'deep_linking_settings'] = {
                'deep_link_return_url': f'{self.issuer}/dl-return', 'accept_types': ['ltiResourceLink'],
                'accept_presentation_document_targets': ['iframe', 'window'], 'data': 'opaque-42'}
        key = self.other_key if launch['forge'] == 'key' else self.key
        return jwt.encode(claims, key, algorithm='RS256', headers={'kid': self.kid})


class _H(tornado.web.RequestHandler):
    def initialize(self, p: Platform) -> None:
        self.p = p

    def check_xsrf_cookie(self) -> None:
        pass


class Jwks(_H):
    def get(self) -> None:
        jwk = json.loads(jwt.algorithms.RSAAlgorithm.to_jwk(self.p.key.public_key()))
        self.finish({'keys': [{**jwk, 'kid': self.p.kid, 'alg': 'RS256', 'use': 'sig'}]})


class Start(_H):
    def get(self) -> None:
        lid = self.get_argument('launch')
        launch = self.p.launches[lid]
        self.finish(form_page(f'{self.p.tool}/lti/login', {
            'iss': self.p.issuer, 'login_hint': launch['sub'], 'target_link_uri': launch['target'],
            'lti_message_hint': lid, 'client_id': self.p.client_id, 'lti_deployment_id': self.p.deployment}))


class Auth(_H):
    def get(self) -> None:
        a = self.get_argument
        assert a('redirect_uri') == f'{self.p.tool}/lti/launch', a('redirect_uri')
        assert a('client_id') == self.p.client_id and a('response_mode') == 'form_post'
        assert a('scope') == 'openid' and a('response_type') == 'id_token' and a('prompt') == 'none'
        launch = self.p.launches[a('lti_message_hint')]
        if launch['forge'].startswith('replay:'):     # an earlier launch's id_token, with this login's state
            token = self.p.posted[int(launch['forge'].split(':')[1])]['id_token']
        else:
            token = self.p.id_token(launch, a('nonce'))
        state = uuid.uuid4().hex if launch['forge'] == 'state' else a('state')
        self.p.posted.append({'id_token': token, 'state': state, 'launch': launch})
        self.finish(form_page(a('redirect_uri'), {'id_token': token, 'state': state}))


class Repost(_H):
    """GET /post?i=N: the N-th id_token this platform posted, posted again (a replay)."""

    def get(self) -> None:
        sent = self.p.posted[int(self.get_argument('i'))]
        self.finish(form_page(f'{self.p.tool}/lti/launch', {'id_token': sent['id_token'], 'state': sent['state']}))


class Course(_H):
    """GET /course?launch=ID: a course page with the activity in an iframe, as an LMS shows it."""

    def get(self) -> None:
        self.finish('<!doctype html><title>course</title><h1>Robotics 101</h1>'
                    f'<iframe id="tool" width="1000" height="700" src="/start?launch={self.get_argument("launch")}">'
                    '</iframe>')


class DlReturn(_H):
    def post(self) -> None:
        self.p.returned.append(self.get_argument('JWT'))
        self.finish('<!doctype html><p id="done">added to the course</p>')
