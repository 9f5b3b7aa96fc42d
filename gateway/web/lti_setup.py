"""Setting rosgate up in an LMS, and the LTI routes in one table:

- ``GET /lti/config``: what the LMS needs, for Moodle and Canvas: the one-step registration
  (LTI Dynamic Registration), the values to paste by hand, and how to turn on grades (Assignment
  and Grade Services) and the roster (Names and Role Provisioning) with the ``--lti`` file's keys
  they need; then the platforms registered.
- ``POST /lti/register/new`` (a signed-in admin): a registration URL, good once for an hour.
- ``GET /lti/register?ticket=T&openid_configuration=URL&registration_token=TOKEN``: the platform
  opens the URL so (IMS LTI Dynamic Registration 1.0); the tool fetches the platform's OpenID
  configuration, registers itself at its registration endpoint, keeps the answer (``auth.lti_dynamic``)
  and closes the LMS's dialog (``postMessage({subject: 'org.imsglobal.lti.close'})``). A URL used,
  expired or not made by an admin of this gateway registers nothing.
"""

from __future__ import annotations

import html
import json
import logging

import tornado.httpclient
import tornado.web
from tornado.httpclient import HTTPRequest

from ..auth import lti_dynamic
from ..rules.access import Action, Area, allowed
from ..auth.lti_dynamic import RegistrationError
from ..auth.tokens import AuthError
from .api import check_origin
from .language import Texts
from .lti import DeepLinkHandler, JwksHandler, LaunchHandler, LoginInitHandler, Lti, ResumeHandler, LtiPage, base_url

log = logging.getLogger('rosgate.lti')
MAX_ANSWER = 1 << 20      # bytes of the platform's configuration or registration answer
TIMEOUT = 20.0            # s for each of the platform's answers

MOODLE, CANVAS = 'Moodle 4.x (External tool)', 'Canvas (Developer key, LTI key)'
GRADES_MOODLE = ('Services: <b>IMS LTI Assignment and Grade Services</b> &rarr; <i>Use this service for grade sync '
                 'and column management</i>; Privacy: <i>Accept grades from the tool</i> &rarr; Always')
ROSTER_MOODLE = ('Services: <b>IMS LTI Names and Role Provisioning</b> &rarr; <i>Use this service to retrieve '
                 'members\' information as per privacy settings</i>; Privacy: <i>Share launcher\'s name with '
                 'tool</i> &rarr; Always')
GRADES_CANVAS = ('LTI Advantage Services: <i>Can create and view assignment data in the gradebook associated with '
                 'the tool</i>, <i>Can view assignment data in the gradebook associated with the tool</i>, <i>Can '
                 'view submission data for assignments associated with the tool</i> and <i>Can create and update '
                 'submission results for assignments associated with the tool</i>')
ROSTER_CANVAS = ('LTI Advantage Services: <i>Can retrieve user data associated with the context the tool is '
                 'installed in</i>; Additional Settings: Privacy Level <i>Public</i>')


def _identity(handler):
    try:
        return handler.lti.policy.identity_of(handler.request)
    except AuthError:
        return None


class ConfigHandler(LtiPage):
    async def get(self) -> None:
        b = html.escape(base_url(self))
        hand = [
            ('Tool URL / Target Link URI', 'Tool URL', 'Target Link URI', f'{b}/'),
            ('Login initiation', 'Initiate login URL', 'OpenID Connect Initiation Url', f'{b}/lti/login'),
            ('Redirect URI', 'Redirection URI(s)', 'Redirect URIs', f'{b}/lti/launch'),
            ('Tool keys', 'Public keyset (Public key type: Keyset URL)', 'Public JWK URL (JWK Method)',
             f'{b}/lti/jwks'),
            ('Deep linking', 'Content Selection URL (tick Supports Deep Linking)',
             'Link Selection placement, message type LtiDeepLinkingRequest', f'{b}/lti/launch'),
        ]
        rows = ''.join(f'<tr><td>{w}</td><td>{m}</td><td>{c}</td><td><code>{u}</code></td></tr>' for w, m, c, u in hand)
        services = (f'<tr><td>Grades (AGS)</td><td>{GRADES_MOODLE}</td><td>{GRADES_CANVAS}</td>'
                    '<td><code>auth_token_url</code></td></tr>'
                    f'<tr><td>Roster (NRPS)</td><td>{ROSTER_MOODLE}</td><td>{ROSTER_CANVAS}</td>'
                    '<td><code>auth_token_url</code> (and <code>memberships_urls</code>)</td></tr>')
        if allowed(_identity(self), Action.MANAGE, Area.COURSE):
            register = ('<form method="post" action="/lti/register/new"><button type="submit" id="new-registration">'
                        'Make a registration URL</button> (good once, for an hour)</form>')
        else:
            register = '<p>An admin of this gateway makes the URL here: <a href="/login?next=/lti/config">sign in</a>.</p>'
        regs = ''.join(f'<li><code>{html.escape(r.issuer)}</code> client <code>{html.escape(r.client_id)}</code>, '
                       f'deployments {html.escape(", ".join(r.deployment_ids) or "any of this client")}'
                       f'{"" if r.auth_token_url else " &mdash; <b>no auth_token_url: no grades, no roster</b>"}</li>'
                       for r in self.lti.config.registrations)
        example = html.escape(json.dumps({'https://moodle.school.example': {
            'client_id': 'the Client ID', 'deployment_ids': ['1'],
            'auth_login_url': 'https://moodle.school.example/mod/lti/auth.php',
            'key_set_url': 'https://moodle.school.example/mod/lti/certs.php',
            'auth_token_url': 'https://moodle.school.example/mod/lti/token.php',
            'memberships_urls': ['(optional) a course\'s context_memberships_url']}}, indent=1))
        self.page('rosgate: LTI 1.3 configuration', f"""<h1>Add rosgate to an LMS (LTI 1.3)</h1>
<h2>In one step: LTI Dynamic Registration</h2>
<p>Moodle 4.x: Site administration &rsaquo; Plugins &rsaquo; Activity modules &rsaquo; External tool &rsaquo; Manage
tools: paste the registration URL into <i>Tool URL</i> and press <i>Add LTI Advantage</i>, then activate the tool.
Canvas: Admin &rsaquo; Developer Keys &rsaquo; + Developer Key &rsaquo; + LTI Registration: paste the URL; turn the
key on, then add the app by its Client ID (Settings &rsaquo; Apps). rosgate registers its login, launch, keys, deep
linking and asks for grades (Assignment and Grade Services) and the roster (Names and Role Provisioning); the
platform's answer is kept here, and no file needs editing.</p>{register}
<h2>By hand</h2><table><tr><th></th><th>{MOODLE}</th><th>{CANVAS}</th><th>Value</th></tr>{rows}</table>
<p>Custom parameters (optional): <code>page=teleop</code> (or ide, class), <code>station=s03</code>,
<code>program=NAME</code>.</p>
<p>Then give the platform's values to the <code>--lti</code> file (one entry per platform):
<code>client_id</code>, <code>deployment_ids</code>, <code>auth_login_url</code> (Moodle: Authentication request
URL; Canvas: <code>https://CANVAS/api/lti/authorize_redirect</code>) and <code>key_set_url</code> (Moodle: Public
keyset URL; Canvas: <code>https://CANVAS/api/lti/security/jwks</code>).</p>
<h2>Grades and the roster (LTI Advantage)</h2>
<p>Scores of exercises go to the LMS gradebook by the <b>Assignment and Grade Services</b> (AGS), the course's
members to the class view by <b>Names and Role Provisioning Services</b> (NRPS). Both need the service turned on in
the LMS and the platform's token endpoint in the <code>--lti</code> file as <code>auth_token_url</code> (Moodle:
Access token URL, <code>https://MOODLE/mod/lti/token.php</code>; Canvas: <code>https://CANVAS/login/oauth2/token</code>);
without it no score is posted and no roster is read. <code>memberships_urls</code> (optional) lists courses
whose roster is read at start, before anyone launches; each launch brings its own course's.</p>
<table><tr><th></th><th>{MOODLE}</th><th>{CANVAS}</th><th>--lti key</th></tr>{services}</table>
<p>A graded exercise is added to a course by deep linking (the teacher picks it): the platform then makes its
gradebook column, and each attempt's score goes there.</p>
<pre>{example}</pre>
<h2>Platforms registered (--lti {html.escape(self.lti.config.path)}, and by Dynamic Registration)</h2>
<ul>{regs}</ul>""")


class RegisterLinkHandler(LtiPage):
    async def post(self) -> None:
        check_origin(self, self.lti.policy)
        who = _identity(self)
        if not allowed(who, Action.MANAGE, Area.COURSE):
            self.refuse('a registration URL is made by an admin of this gateway: sign in as one', 403)
            return
        ticket = await self.lti.store.run(lambda c: lti_dynamic.make_link(c, who.name))
        url = html.escape(f'{base_url(self)}/lti/register?ticket={ticket}')
        log.info('lti: %s made a registration URL', who.name)
        self.page('rosgate: registration URL', f'<h1>Registration URL</h1><p><code id="url">{url}</code></p>'
                  f'<p>Paste it into the LMS within {lti_dynamic.LINK_TTL / 3600:g} hour; it registers one platform '
                  'once. <a href="/lti/config">Back</a></p>')


class RegisterHandler(LtiPage):
    async def get(self) -> None:
        arg = self.get_argument
        config_url, token = arg('openid_configuration', ''), arg('registration_token', None)
        if not config_url:
            self.refuse('a registration starts in the LMS: paste this URL there (it adds openid_configuration)')
            return
        who = await self.lti.store.run(lambda c: lti_dynamic.take_link(c, arg('ticket', '')))
        if who is None:
            self.refuse('this registration URL is used, more than an hour old, or not one an admin of this gateway '
                        'made: make a new one at /lti/config', 403)
            return
        try:
            lti_dynamic.secure_url(config_url, 'openid_configuration')
            platform = lti_dynamic.check_platform(config_url, await _fetch(config_url, token))
            answer = await _fetch(platform['registration_endpoint'], token,
                                  lti_dynamic.tool_registration(base_url(self), platform))
            reg, product, scopes = lti_dynamic.registration_of(platform, answer)
        except RegistrationError as e:
            self.refuse(f'not registered: {e}', 502)
            return
        await self.lti.store.run(lambda c: lti_dynamic.save(c, reg, product, scopes, who))
        self.lti.config.add(reg)
        log.info('lti: %s registered %s (%s) as client %s, deployments %s, by %s', product or 'a platform',
                 reg.issuer, scopes, reg.client_id, reg.deployment_ids or 'any', who)
        granted = ', '.join(s.rsplit('/', 1)[-1] for s in scopes.split()) or 'none'
        self.page('rosgate: registered',
                  f'<h1>rosgate is registered</h1><p id="registered">{html.escape(product or reg.issuer)}: client '
                  f'<code>{html.escape(reg.client_id)}</code>, deployment '
                  f'<code>{html.escape(", ".join(reg.deployment_ids) or "any")}</code>; services: '
                  f'{html.escape(granted)}.</p>'
                  f'<script nonce="{self.script_nonce}">(window.opener || window.parent)'
                  ".postMessage({subject: 'org.imsglobal.lti.close'}, '*');</script>")


async def _fetch(url: str, token: str | None, body: dict | None = None):
    """The platform's JSON answer to a GET (or a POST of ``body``), the registration token as bearer."""
    headers = {'Accept': 'application/json'}
    if token:
        headers['Authorization'] = f'Bearer {token}'
    if body is not None:
        headers['Content-Type'] = 'application/json'
    client = tornado.httpclient.AsyncHTTPClient(force_instance=True, max_body_size=MAX_ANSWER)
    what = 'registration' if body is not None else 'OpenID configuration'
    try:
        response = await client.fetch(HTTPRequest(
            lti_dynamic.secure_url(url, what), method='POST' if body is not None else 'GET', headers=headers,
            body=json.dumps(body) if body is not None else None, follow_redirects=False, request_timeout=TIMEOUT))
        return json.loads(response.body)
    except tornado.httpclient.HTTPClientError as e:
        said = e.response.body.decode(errors='replace')[:300] if e.response is not None and e.response.body else ''
        raise RegistrationError(f'the platform answered the {what} with {e.code}: {said}') from None
    except (OSError, ValueError) as e:
        raise RegistrationError(f'the platform\'s {what} at {url[:200]}: {e}') from None
    finally:
        client.close()


def lti_routes(config, policy, examples_dir, texts: Texts, store=None, exercises=None) -> list:
    shared = {'lti_': Lti(config, policy, examples_dir, texts, store, exercises)}
    routes = [(r'/lti/login', LoginInitHandler, shared), (r'/lti/launch', LaunchHandler, shared),
              (r'/lti/deeplink', DeepLinkHandler, shared), (r'/lti/resume', ResumeHandler, shared),
              (r'/lti/jwks', JwksHandler, shared), (r'/lti/config', ConfigHandler, shared)]
    if store is not None:
        routes += [(r'/lti/register/new', RegisterLinkHandler, shared), (r'/lti/register', RegisterHandler, shared)]
    return routes
