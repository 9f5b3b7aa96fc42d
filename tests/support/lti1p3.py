"""An LTI 1.3 platform that is not the project's own: PyPI's ``lti1p3platform`` (its launch,
deep linking, access token, AGS and NRPS classes) served on loopback by a small tornado app in a
thread of the test process, the way a Django or FastAPI LMS would mount them. What the package
leaves to its host (the course, its links, the gradebook, the members) is kept here in memory:

- ``/start?launch=ID``: the OIDC login initiation (``OIDCLoginAbstract.initiate_login``: a redirect
  to the tool's /lti/login); ``/auth``: the authorization endpoint, answered with the auto-posted
  id_token of ``LTIAdvantageMessageLaunchAbstract`` (resource link, context, custom parameters, and
  the AGS and NRPS claims; a deep linking request for ``kind='dl'``);
- ``/token``: ``get_access_token`` (the tool's client-credentials JWT checked against its JWKS);
- ``/lineitems``, ``/lineitems/ID``, ``/lineitems/ID/scores``, ``/lineitems/ID/results``:
  ``AssignmentsGradesService``; ``/memberships``: ``NamesRoleProvisioningService``;
- ``/dl-return``: ``validate_deeplinking_resp``; each ``ltiResourceLink`` item becomes a resource
  link of the course, and its ``lineItem`` a gradebook column (line item) bound to it.

``gradebook`` is every score the tool posted, as (line item id, score JSON).

LTI Dynamic Registration 1.0, which the package does not do, is this platform's own (as Moodle 4.x
does it): ``/.well-known/openid-configuration`` (only with the registration token as a bearer),
``/register`` (the tool's client registration, with that token, once: it gets a new client id and
deployment, and its login, launch and key set URLs become the platform's registration of the tool),
and ``/lms-admin?tool_url=URL``: the admin's page that opens the tool's registration URL in a frame
with ``openid_configuration`` and ``registration_token``, and closes it on the tool's
``org.imsglobal.lti.close`` message (``body[data-closed]``).
"""

from __future__ import annotations

import html
import itertools
import json
import re
import typing as t
from urllib.parse import quote, urlencode, urlsplit
import secrets

import tornado.web
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric import rsa
from lti1p3platform.exceptions import LineItemNotFoundException
from lti1p3platform.ltiplatform import LTI1P3PlatformConfAbstract
from lti1p3platform.membership import Context
from lti1p3platform.message_launch import LTIAdvantageMessageLaunchAbstract
from lti1p3platform.oidc_login import OIDCLoginAbstract
from lti1p3platform.registration import Registration
from lti1p3platform.request import Request, TRequest
from lti1p3platform.score import UpdateScoreStatus
from lti1p3platform.service_connector import AssignmentsGradesService, NamesRoleProvisioningService

from tests.support.lti_platform import Served

LEARNER = 'http://purl.imsglobal.org/vocab/lis/v2/membership#Learner'
INSTRUCTOR = 'http://purl.imsglobal.org/vocab/lis/v2/membership#Instructor'
COURSE = {'id': 'robotics-101', 'label': 'ROB101', 'title': 'Robotics 101'}


def _pem(key, private: bool) -> str:
    if private:
        return key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                                 serialization.NoEncryption()).decode()
    return key.public_key().public_bytes(serialization.Encoding.PEM,
                                         serialization.PublicFormat.SubjectPublicKeyInfo).decode()


class TornadoRequest(Request):
    """The package's request, built from a tornado request (as its Django and FastAPI ones are)."""

    def build_metadata(self, request) -> TRequest:
        kind = request.headers.get('Content-Type', '')
        form = {k: v[0].decode() for k, v in request.body_arguments.items()} if 'form' in kind else {}
        return {'method': request.method, 'form_data': form,
                'get_data': {k: int(v[0]) if v[0].isdigit() else v[0].decode()   # page, limit: numbers
                             for k, v in request.query_arguments.items()},
                'headers': request.headers, 'content_type': kind, 'path': request.path,
                'json': json.loads(request.body) if request.body and 'json' in kind else None}


class PlatformConf(LTI1P3PlatformConfAbstract):
    def init_platform_config(self, **kw) -> None:
        self._registration = kw['registration']

    def get_registration_by_params(self, **kw) -> Registration:
        return self._registration


class Login(OIDCLoginAbstract):
    def set_lti_message_hint(self, **kw) -> None:
        self._lti_message_hint = kw['hint']

    def get_redirect(self, url: str) -> str:
        return url


class Launch(LTIAdvantageMessageLaunchAbstract):
    platform: 'Platform'

    def prepare_launch(self, preflight_response: dict) -> None:
        p = self.platform
        launch = p.launches[preflight_response['lti_message_hint']]
        self.set_user_data(launch['sub'], launch['roles'], full_name=launch['name'])
        self.set_launch_context_claim(COURSE['id'], context_title=COURSE['title'], context_label=COURSE['label'])
        self.set_nrps(p.url('/memberships?limit=2'))   # two a page: the tool follows Link rel="next"
        if launch['kind'] == 'dl':
            self.set_dl(p.url('/dl-return'), title='Robotics 101', accept_types={'ltiResourceLink'},
                        extra_data={'opaque': '42'})
            return
        link = p.links[launch['link']]
        self.set_resource_link_claim(launch['link'], title=link['title'])
        if link.get('custom'):
            self.set_custom_parameters_claim(link['custom'])
        item = link.get('lineitem')
        self.set_ags(p.url('/lineitems'), p.url(f'/lineitems/{item}') if item else None)

    def render_launch_form(self, launch_data: dict, **kw) -> str:
        inputs = ''.join(f'<input type="hidden" name="{k}" value="{html.escape(launch_data[k])}">'
                         for k in ('id_token', 'state'))
        return (f'<!doctype html><form id="f" method="post" action="{html.escape(launch_data["launch_url"])}">'
                f'{inputs}</form><script>document.getElementById("f").submit()</script>')


class Grades(AssignmentsGradesService):
    platform: 'Platform'

    def find_lineitems(self, page=1, limit=None, line_item_id=None, resource_link_id=None, resource_id=None,
                       tag=None, **kw):
        items = [i for i in self.platform.lineitems.values()
                 if resource_id in (None, i['resourceId']) and resource_link_id in (None, i.get('resourceLinkId'))]
        return {'content': items, 'has_next': False, 'next': None}

    def find_lineitem(self, line_item_id: str):
        if line_item_id not in self.platform.lineitems:
            raise LineItemNotFoundException()
        return self.platform.lineitems[line_item_id]

    def create_lineitem(self, creation_data):
        return self.platform.new_lineitem(dict(creation_data))

    def update_lineitem(self, update_data):
        self.find_lineitem(update_data['id']).update(update_data)
        return self.platform.lineitems[update_data['id']]

    def delete_lineitem(self, line_item_id: str) -> None:
        self.find_lineitem(line_item_id)
        del self.platform.lineitems[line_item_id]

    def update_score(self, line_item_id: str, score) -> UpdateScoreStatus:
        self.find_lineitem(line_item_id)
        self.platform.gradebook.append((line_item_id, dict(score)))
        return UpdateScoreStatus.SUCCESS

    def get_results(self, line_item_id, page=1, limit=None, user_id=None, **kw):
        self.find_lineitem(line_item_id)
        rows = [{'userId': s['userId'], 'resultScore': s['scoreGiven'], 'resultMaximum': s['scoreMaximum'],
                 'comment': s.get('comment')} for i, s in self.platform.gradebook if i == line_item_id
                and user_id in (None, s['userId'])]
        return {'content': rows, 'has_next': False, 'next': None}


class Roster(NamesRoleProvisioningService):
    platform: 'Platform'

    def get_context_by_id(self) -> Context:
        return Context(**COURSE)

    def get_member_data_page(self, page=1, limit=None, role=None, since=None, **kw):
        members = [dict(m) for m in self.platform.members]
        if limit is None:
            return {'content': members, 'has_next': False, 'next': None}
        return {'content': members[(page - 1) * limit:page * limit], 'has_next': page * limit < len(members),
                'next': None}


class Platform:
    """The platform, its course and gradebook; ``tool`` is the gateway's base URL (set once known)."""

    def __init__(self, client_id: str = 'rosgate-1p3', deployment: str = 'dep-1'):
        self.client_id, self.deployment, self.tool = client_id, deployment, ''
        key = rsa.generate_private_key(public_exponent=65537, key_size=2048)
        self.public_pem, self.private_pem = _pem(key, False), _pem(key, True)
        self.ids = itertools.count(1)
        self.launches: dict[str, dict] = {}
        self.links: dict[str, dict] = {}         # resource link id -> {title, custom, lineitem}
        self.lineitems: dict[str, dict] = {}     # line item id -> its JSON
        self.gradebook: list[tuple[str, dict]] = []
        self.members: list[dict] = []
        self.returned: list[list[dict]] = []     # content items of each deep linking response
        self.registration_token: str | None = None   # a Dynamic Registration's token, good once
        self.registered: list[dict] = []         # the tool registrations posted, as posted
        self.tool_urls: dict | None = None       # the registered tool's login, launch and key set URLs
        self.served = Served([
            (r'/jwks', Jwks), (r'/start', Start), (r'/auth', Auth), (r'/token', Token),
            (r'/lineitems/?', LineItems), (r'/lineitems/([^/]+)', LineItem),
            (r'/lineitems/([^/]+)/scores', Scores), (r'/lineitems/([^/]+)/results', Results),
            (r'/memberships', Memberships), (r'/dl-return', DlReturn),
            (r'/.well-known/openid-configuration', OpenIdConfiguration), (r'/register', Register),
            (r'/lms-admin', LmsAdmin)], {'p': self})
        self.issuer = f'http://127.0.0.1:{self.served.port}'

    def url(self, path: str) -> str:
        return self.issuer + path

    def stop(self) -> None:
        self.served.stop()

    def conf(self) -> PlatformConf:
        urls = self.tool_urls or {'launch': self.tool + '/', 'deeplink': self.tool + '/lti/launch',
                                  'login': self.tool + '/lti/login', 'jwks': self.tool + '/lti/jwks'}
        reg = (Registration().set_iss(self.issuer).set_client_id(self.client_id).set_deployment_id(self.deployment)
               .set_launch_url(urls['launch']).set_deeplink_launch_url(urls['deeplink'])
               .set_oidc_login_url(urls['login']).set_tool_key_set_url(urls['jwks'])
               .set_platform_public_key(self.public_pem).set_platform_private_key(self.private_pem))
        return PlatformConf(registration=reg)

    def openid_configuration(self) -> dict:
        return {
            'issuer': self.issuer, 'authorization_endpoint': self.url('/auth'), 'token_endpoint': self.url('/token'),
            'jwks_uri': self.url('/jwks'), 'registration_endpoint': self.url('/register'),
            'token_endpoint_auth_methods_supported': ['private_key_jwt'],
            'token_endpoint_auth_signing_alg_values_supported': ['RS256'],
            'scopes_supported': ['openid', 'https://purl.imsglobal.org/spec/lti-ags/scope/lineitem',
                                 'https://purl.imsglobal.org/spec/lti-ags/scope/lineitem.readonly',
                                 'https://purl.imsglobal.org/spec/lti-ags/scope/result.readonly',
                                 'https://purl.imsglobal.org/spec/lti-ags/scope/score',
                                 'https://purl.imsglobal.org/spec/lti-nrps/scope/contextmembership.readonly'],
            'response_types_supported': ['id_token'], 'subject_types_supported': ['public', 'pairwise'],
            'id_token_signing_alg_values_supported': ['RS256'], 'claims_supported': ['sub', 'iss', 'name'],
            'https://purl.imsglobal.org/spec/lti-platform-configuration': {
                'product_family_code': 'rosgate-test-lms', 'version': '1.0',
                'messages_supported': [{'type': 'LtiResourceLinkRequest'}, {'type': 'LtiDeepLinkingRequest'}]},
        }

    def registration_page(self, tool_url: str) -> str:
        """A new registration token, and the LMS admin's page that opens ``tool_url`` with it."""
        self.registration_token = secrets.token_urlsafe(16)
        return self.url(f'/lms-admin?tool_url={quote(tool_url, safe="")}')

    def tool_config(self, private_key_file: str, memberships: bool = True) -> dict:
        """This platform in the tool's configuration (PyLTI1p3's format)."""
        return {self.issuer: [{'client_id': self.client_id, 'auth_login_url': self.url('/auth'),
                               'auth_token_url': self.url('/token'), 'key_set_url': self.url('/jwks'),
                               'private_key_file': private_key_file, 'deployment_ids': [self.deployment],
                               **({'memberships_urls': [self.url('/memberships?limit=2')]} if memberships else {})}]}

    def new_lineitem(self, data: dict) -> dict:
        item = f'li{next(self.ids)}'
        self.lineitems[item] = {**data, 'id': self.url(f'/lineitems/{item}')}
        return self.lineitems[item]

    def add_link(self, title: str, custom: dict | None = None, lineitem: dict | None = None) -> str:
        """A resource link in the course (what a teacher adds by hand, or a deep link adds)."""
        link = f'rl{next(self.ids)}'
        item = None
        if lineitem is not None:
            item = self.new_lineitem({**lineitem, 'resourceLinkId': link})['id'].rsplit('/', 1)[1]
        self.links[link] = {'title': title, 'custom': custom or {}, 'lineitem': item}
        return link

    def add(self, sub: str, roles: list[str], *, name: str = '', link: str = '', kind: str = 'link') -> str:
        """A launch of ``link`` (or a deep linking request: kind 'dl'); the URL that starts it."""
        lid = f'launch-{next(self.ids)}'
        self.launches[lid] = {'sub': sub, 'roles': roles, 'name': name or sub, 'link': link, 'kind': kind}
        return self.url(f'/start?launch={lid}')

    def scores(self, link: str, sub: str | None = None) -> list[dict]:
        """The gradebook's scores of the line item bound to ``link`` (of ``sub``)."""
        item = self.links[link]['lineitem']
        return [s for i, s in self.gradebook if i == item and sub in (None, s['userId'])]


class _H(tornado.web.RequestHandler):
    def initialize(self, p: Platform) -> None:
        self.p = p

    def check_xsrf_cookie(self) -> None:
        pass

    def answer(self, resp) -> None:
        """A service's Response, as the package's Django wrapper sends it."""
        self.set_status(resp.code)
        self.set_header('Content-Type', resp.media_type)
        if 200 <= resp.code < 300:
            result = resp.result['content'] if isinstance(resp.result, dict) and 'content' in resp.result \
                else resp.result
            if isinstance(resp.result, dict) and resp.result.get('next'):
                self.set_header('Link', f'<{resp.result["next"]}>; rel="next"')
            if result is not None:
                self.finish(json.dumps(result))
            else:
                self.finish()
        else:
            self.finish(json.dumps({'error': resp.message}))

    def service(self, kind: type, **kw) -> t.Any:
        service = kind(TornadoRequest(self.request), self.p.conf(), **kw)
        service.platform = self.p
        return service

    def grades(self, item: str | None = None) -> Grades:
        return self.service(Grades, lineitems_url=self.p.url('/lineitems'),
                            lineitem_url=self.p.url(f'/lineitems/{item}') if item else None)


class Jwks(_H):
    def get(self) -> None:
        self.finish(self.p.conf().get_jwks())


class Start(_H):
    def get(self) -> None:
        conf = self.p.conf()
        login = Login(self.request, conf)
        launch = self.p.launches[self.get_argument('launch')]
        login.set_lti_message_hint(hint=self.get_argument('launch'))
        if launch['kind'] == 'dl':
            login.set_deeplinking_launch_url()
        self.redirect(login.initiate_login(launch['sub']))


class Auth(_H):
    def get(self) -> None:
        launch = Launch(TornadoRequest(self.request), self.p.conf())
        launch.platform = self.p
        self.finish(launch.lti_launch())


class Token(_H):
    def post(self) -> None:
        conf = self.p.conf()
        conf.get_registration()
        try:
            token = conf.get_access_token({k: v[0].decode() for k, v in self.request.body_arguments.items()})
        except Exception as e:   # the package's refusals (a bad assertion, a missing claim)
            self.set_status(400)
            self.finish({'error': 'invalid_client', 'error_description': str(e)[:300]})
            return
        self.finish(token)


class LineItems(_H):
    def get(self) -> None:
        g = self.grades()
        self.answer(g.handle_resp(g.handle_get_lineitems))

    def post(self) -> None:
        g = self.grades()
        self.answer(g.handle_resp(g.handle_create_lineitem))


class LineItem(_H):
    def get(self, item: str) -> None:
        g = self.grades(item)
        self.answer(g.handle_resp(g.handle_get_lineitem, line_item_id=item))


class Scores(_H):
    def post(self, item: str) -> None:
        g = self.grades(item)
        self.answer(g.handle_resp(g.handle_update_score, line_item_id=item))


class Results(_H):
    def get(self, item: str) -> None:
        g = self.grades(item)
        self.answer(g.handle_resp(g.handle_get_results, line_item_id=item))


class Memberships(_H):
    def get(self) -> None:
        s = self.service(Roster, context_memberships_url=self.p.url('/memberships'))
        self.answer(s.handle_resp(s.handle_get_members))


class DlReturn(_H):
    def post(self) -> None:
        conf = self.p.conf()
        conf.get_registration()
        items = conf.validate_deeplinking_resp({'JWT': self.get_argument('JWT')})
        self.p.returned.append(items)
        for item in items:
            if item.get('type') == 'ltiResourceLink':
                self.p.add_link(item.get('title', ''), item.get('custom'), item.get('lineItem'))
        self.finish('<!doctype html><p id="done">added to the course</p>')


TOOL_CONFIG = 'https://purl.imsglobal.org/spec/lti-tool-configuration'


class OpenIdConfiguration(_H):
    def get(self) -> None:
        if not self.p.registration_token or \
                self.request.headers.get('Authorization') != f'Bearer {self.p.registration_token}':
            self.set_status(401)
            self.finish({'error': 'the registration token is required'})
            return
        self.finish(self.p.openid_configuration())


class Register(_H):
    """The tool's client registration (OpenID Connect Dynamic Client Registration, LTI's claim)."""

    def post(self) -> None:
        token, self.p.registration_token = self.p.registration_token, None    # good once
        if not token or self.request.headers.get('Authorization') != f'Bearer {token}':
            self.set_status(401)
            self.finish({'error': 'invalid_token'})
            return
        body = json.loads(self.request.body)
        self.p.registered.append(body)
        tool = body.get(TOOL_CONFIG) or {}
        problems = [k for k, ok in (
            ('application_type', body.get('application_type') == 'web'),
            ('grant_types', {'implicit', 'client_credentials'} <= set(body.get('grant_types', []))),
            ('response_types', body.get('response_types') == ['id_token']),
            ('initiate_login_uri', str(body.get('initiate_login_uri', '')).startswith('http')),
            ('redirect_uris', bool(body.get('redirect_uris'))), ('jwks_uri', bool(body.get('jwks_uri'))),
            ('token_endpoint_auth_method', body.get('token_endpoint_auth_method') == 'private_key_jwt'),
            ('messages', {m.get('type') for m in tool.get('messages', [])} >= {'LtiDeepLinkingRequest'}),
            ('domain', tool.get('domain') == urlsplit(body.get('initiate_login_uri', '')).netloc)) if not ok]
        if problems:
            self.set_status(400)
            self.finish({'error': 'invalid_client_metadata', 'error_description': ', '.join(problems)})
            return
        n = len(self.p.registered)
        self.p.client_id, self.p.deployment = f'dr-client-{n}', f'dr-deployment-{n}'
        deeplink = next(m['target_link_uri'] for m in tool['messages'] if m['type'] == 'LtiDeepLinkingRequest')
        self.p.tool_urls = {'launch': tool['target_link_uri'], 'deeplink': deeplink,
                            'login': body['initiate_login_uri'], 'jwks': body['jwks_uri']}
        self.p.tool = tool['target_link_uri'].rstrip('/')
        self.finish({**body, 'client_id': self.p.client_id,
                     TOOL_CONFIG: {**tool, 'deployment_id': self.p.deployment}})


class LmsAdmin(_H):
    def get(self) -> None:
        tool_url = self.get_argument('tool_url')
        params = urlencode({'openid_configuration': self.p.url('/.well-known/openid-configuration'),
                            'registration_token': self.p.registration_token or ''})
        src = tool_url + ('&' if '?' in tool_url else '?') + params
        self.finish('<!doctype html><title>LMS admin</title><h1>Register a tool</h1>'
                    f'<iframe id="tool" width="900" height="500" src="{html.escape(src)}"></iframe><script>'
                    "addEventListener('message', (e) => { if (e.data?.subject === 'org.imsglobal.lti.close') {"
                    " document.body.dataset.closed = 'yes'; document.getElementById('tool').remove(); } });"
                    '</script>')


FORM_FIELD = re.compile(r'<input type="hidden" name="([^"]+)" value="([^"]*)">')
FORM_ACTION = re.compile(r'<form id="f" method="post" action="([^"]+)">')


def form_of(page: str) -> tuple[str, dict]:
    """(action, fields) of an auto-posted form (the platform's launch, the tool's deep link answer)."""
    action = FORM_ACTION.search(page)
    assert action, page[:500]
    return html.unescape(action.group(1)), {k: html.unescape(v) for k, v in FORM_FIELD.findall(page)}


__all__ = ['INSTRUCTOR', 'LEARNER', 'Platform', 'form_of', 'urlencode']
