"""LTI 1.3 routes: an LMS (Moodle, Canvas, any LTI 1.3 platform) launches rosgate.

- ``GET|POST /lti/login``: OIDC third-party login initiation. A fresh ``state`` and ``nonce`` are
  kept on the server for ``PENDING_TTL`` s; the state is also set as a cookie of this browser
  (``rosgate_lti_<state>``, SameSite=None; Secure; Partitioned, the only kind that survives
  inside an LMS's iframe in Chromium and that a cross-site form post carries); then the browser
  goes to the platform's authorization endpoint.
- ``POST /lti/launch``: the platform's form post of ``id_token`` and ``state``. The state must be
  one this gateway gave out and not yet used, and this browser's cookie must hold it; the
  id_token is judged by ``auth.lti.check_launch`` against the platform's key (its JWKS, fetched,
  cached, fetched again for a key id it does not know). Anything wrong: a page saying what (400),
  and nobody is signed in. Otherwise the browser is signed in (the same session as ``/login``)
  and lands where the launch asks (``landing``); a deep linking request gets the picker.
- ``POST /lti/deeplink``: the picker's choice, answered with a signed LtiDeepLinkingResponse
  auto-posted to the platform. An exercise picked (``--exercises-dir``) goes as a resource link
  with a ``lineItem`` (scoreMaximum 1, its title as label, its id as resourceId), so the platform
  makes the gradebook column its scores go to, and custom ``exercise=ID``, so a launch from it
  lands in the IDE on that exercise and its AGS line item is kept for that exercise (``lab.grades``).
- ``GET /lti/resume``: where a launch whose cookie the browser refused (Safari in an iframe)
  continues in a new window, with a ticket good for one use within ``RESUME_TTL`` s.
- ``GET /lti/jwks``: the tool's public keys. The LMS set-up (``/lti/config``, LTI Dynamic
  Registration) and the route table: ``lti_setup``.
"""

from __future__ import annotations

import html
import json
import logging
import secrets
import time
import urllib.parse
from urllib.parse import urlencode, urlsplit

import tornado.ioloop
import tornado.web

from ..auth import lti, lti_dynamic
from ..auth.launch import Expiring, KeySets
from ..lab import grades, roster
from ..lab.landing import deep_link_item, landing_of
from ..rules.access import Action, Area, allowed
from ..auth.lti import LaunchError
from .api import Handler, check_origin
from .cookies import clear_cookie, set_cookie
from .language import Texts, best
from .login import begin_session

log = logging.getLogger('rosgate.lti')
PENDING_TTL = 600.0      # s between the login initiation and the launch
RESUME_TTL = 120.0       # s a "continue in a new window" ticket stays good
RELOAD = 5.0             # s between reads of the platforms registered by LTI Dynamic Registration
STATE_COOKIE = 'rosgate_lti_'


class Lti:
    """What the routes share: the configuration, logins in flight, used states, keys."""

    def __init__(self, config: lti.LtiConfig, policy, examples_dir, texts: Texts, store=None, exercises=None):
        self.config, self.policy, self.examples_dir = config, policy, examples_dir
        self.store = store                         # where launches' AGS line items are kept (grades)
        self.exercises = exercises                 # lab.exercises.Library: what a deep link may pick to grade
        self.texts = texts                         # the pages' words, in the reader's language
        self.pending = Expiring(PENDING_TTL)
        self.used = Expiring(PENDING_TTL)          # states already launched: a replay is told so
        self.resume = Expiring(RESUME_TTL)
        self.picks = Expiring(PENDING_TTL)         # deep linking requests waiting for the teacher's pick
        self.keys = KeySets()
        self.reading: set[str] = set()             # rosters being read from the LMS now (their URLs)
        self.loaded = -1e9                         # monotonic time the platforms registered here were read
        if store is not None:
            tornado.ioloop.IOLoop.current().spawn_callback(self.load_registered)

    async def load_registered(self) -> bool:
        """The platforms registered by LTI Dynamic Registration, read into the configuration (at most
        every ``RELOAD`` s: a launch from an unknown platform reads them again); whether it read."""
        if self.store is None or time.monotonic() - self.loaded < RELOAD:
            return False
        self.loaded = time.monotonic()
        try:
            await self.store.run(lambda c: lti_dynamic.load(c, self.config))
        except Exception:
            log.exception('lti: the registered platforms cannot be read')
            return False
        return True


def base_url(handler: tornado.web.RequestHandler) -> str:
    """This gateway as the browser reaches it (through a trusted proxy: its scheme and host)."""
    return f'{handler.request.protocol}://{handler.request.host}'


PAGE = """<!doctype html><html lang="en"><head><meta charset="utf-8"><meta name="viewport" content="width=device-width">
<title>{title}</title><style>body{{font:16px system-ui,sans-serif;max-width:44rem;margin:3rem auto;padding:0 1rem}}
.msg{{color:#a00}} code{{background:#eee;padding:0 .2em}} td{{padding:.2rem .5rem;vertical-align:top}}
button{{font:inherit;padding:.4rem 1rem;margin:.3rem 0}}</style></head><body>{body}</body></html>"""


class LtiPage(Handler):
    def initialize(self, lti_: Lti) -> None:
        self.lti = lti_
        self.script_nonce = secrets.token_urlsafe(12)

    def set_default_headers(self) -> None:
        self.set_header('Cache-Control', 'no-store')
        self.set_header('Referrer-Policy', 'no-referrer')

    def say(self, key: str, lang: str | None = None, **values) -> str:
        """A text of these pages, HTML-escaped, in `lang` or the browser's language."""
        return html.escape(self.lti.texts.get(lang or self.lti.texts.pick(self), key, **values))

    def page(self, title: str, body: str, status: int = 200) -> None:
        self.set_status(status)
        self.set_header('Content-Type', 'text/html; charset=UTF-8')
        self.set_header('Content-Security-Policy', f"default-src 'self'; style-src 'unsafe-inline'; "
                                                   f"script-src 'nonce-{self.script_nonce}'; form-action *; "
                                                   "frame-ancestors *")
        self.finish(PAGE.format(title=html.escape(title), body=body))

    def refuse(self, reason: str, status: int = 400) -> None:
        log.info('lti: launch refused from %s: %s', self.request.remote_ip, reason)
        self.page('rosgate: ' + self.say('lti.refused.title'),
                  f'<h1>{self.say("lti.refused")}</h1><p class="msg" id="reason">{html.escape(reason)}</p>'
                  f'<p>{self.say("lti.refused.text")}</p>', status)

    def answer_error(self, status_code: int, reason: str) -> None:
        self.refuse(reason, status_code)

    def auto_post(self, action: str, fields: dict, note: str) -> None:
        inputs = ''.join(f'<input type="hidden" name="{html.escape(k)}" value="{html.escape(v)}">'
                         for k, v in fields.items())
        self.page('rosgate', f'<form id="f" method="post" action="{html.escape(action)}">{inputs}'
                             f'<p>{html.escape(note)}</p><button type="submit">{self.say("lti.continue")}</button></form>'
                             f'<script nonce="{self.script_nonce}">document.getElementById("f").submit()</script>')


class LoginInitHandler(LtiPage):
    async def get(self) -> None:
        arg = self.get_argument
        iss, hint = arg('iss', ''), arg('login_hint', '')
        if not iss or not hint:
            raise tornado.web.HTTPError(400, 'an LTI login initiation needs iss and login_hint (start the launch '
                                             'from the course, not from a bookmark)')
        reg = self.lti.config.find(iss, arg('client_id', None) or None)
        if reg is None and await self.lti.load_registered():   # registered through another gateway of a fleet
            reg = self.lti.config.find(iss, arg('client_id', None) or None)
        if reg is None:
            raise tornado.web.HTTPError(400, f'the platform {iss[:200]!r} (client id {arg("client_id", "")[:100]!r}) '
                                             'is not registered with this tool (--lti)')
        deployment = arg('lti_deployment_id', None)
        if deployment is not None and reg.deployment_ids and deployment not in reg.deployment_ids:
            raise tornado.web.HTTPError(400, f'deployment {deployment[:100]!r} of {iss[:200]} is not registered with '
                                             'this tool')
        state, nonce = secrets.token_urlsafe(24), secrets.token_urlsafe(24)
        self.lti.pending.put(state, {'nonce': nonce, 'iss': reg.issuer, 'client_id': reg.client_id})
        set_cookie(self, STATE_COOKIE + state, state, max_age=int(PENDING_TTL), samesite='None', partitioned=True)
        params = {'scope': 'openid', 'response_type': 'id_token', 'response_mode': 'form_post', 'prompt': 'none',
                  'client_id': reg.client_id, 'redirect_uri': base_url(self) + '/lti/launch',
                  'login_hint': hint, 'state': state, 'nonce': nonce}
        if arg('lti_message_hint', None) is not None:
            params['lti_message_hint'] = arg('lti_message_hint')
        sep = '&' if '?' in reg.auth_login_url else '?'
        self.redirect(reg.auth_login_url + sep + urlencode(params))

    post = get


class LaunchHandler(LtiPage):
    async def post(self) -> None:
        if self.get_argument('error', None):
            self.refuse(f'the platform answered {self.get_argument("error")[:100]}: '
                        f'{self.get_argument("error_description", "")[:300]}')
            return
        state, id_token = self.get_argument('state', ''), self.get_argument('id_token', '')
        if not state or not id_token:
            self.refuse('a launch needs state and id_token (start it from the course)')
            return
        cookie = self.get_cookie(STATE_COOKIE + state)
        pending = self.lti.pending.take(state)
        if pending is None:
            if self.lti.used.take(state) is not None:
                self.refuse('this launch was already used: state and nonce are good for one launch (a replayed '
                            'id_token?)')
            else:
                self.refuse('unknown state: this gateway did not start this sign-in, or it is more than '
                            f'{PENDING_TTL / 60:g} minutes old')
            return
        self.lti.used.put(state, True)
        clear_cookie(self, STATE_COOKIE + state, secure=True)
        if cookie != state:
            self.refuse('state mismatch: this browser did not start this launch (its state cookie is missing; '
                        'a browser that blocks cookies in the course\'s frame: open the activity in a new window)')
            return
        try:
            header, unverified = lti.unverified(id_token)
            reg = lti.registration_for(self.lti.config, unverified)
            if (reg.issuer, reg.client_id) != (pending['iss'], pending['client_id']):
                raise LaunchError('the id_token comes from another platform or client than the sign-in began with')
            if header.get('alg') != 'RS256':
                raise LaunchError(f'the id_token is signed with {str(header.get("alg"))[:20]}, not RS256')
            key = await self.lti.keys.key(reg, header.get('kid'))
            claims = lti.check_launch(id_token, key, reg, pending['nonce'])
        except LaunchError as e:
            self.refuse(str(e))
            return
        identity = lti.identity_of(claims)
        framed = self.request.headers.get('Sec-Fetch-Dest', '').lower() == 'iframe'
        log.info('lti: %s (%s) launched from %s', identity.name, identity.role, reg.issuer)
        url = (claims.get(roster.NRPS_CLAIM) or {}).get('context_memberships_url')
        if self.lti.store is not None and isinstance(url, str) and url and url not in self.lti.reading:
            self.lti.reading.add(url)   # the course's roster; a class launching at once reads it once
            self._beside(roster.fetch(self.lti.store, self.lti.config, reg, url), f'roster at {url[:200]}',
                         lambda: self.lti.reading.discard(url))
        if claims[lti.CLAIM + 'message_type'] == lti.DEEP_LINKING:
            self._picker(identity, reg, claims)
            return
        if self.lti.store is not None and await grades.remember_launch(self.lti.store, identity.key, claims) \
                and grades.exercise_of(claims) is None:   # which exercise: the line item's resourceId
            self._beside(grades.resolve(self.lti.store, self.lti.config, identity.key), 'the line item')
        begin_session(self, self.lti.policy, identity, 'lti', framed=framed)
        self.set_header('X-Rosgate-Role', identity.role)
        landing = landing_of(claims)
        ticket = secrets.token_urlsafe(24)
        self.lti.resume.put(ticket, (identity, landing))
        lang = best([urllib.parse.parse_qs(urlsplit(landing).query).get('lang', [''])[0]], self.lti.texts.offered())
        self.page('rosgate', landed_page(landing, ticket, identity, self.script_nonce,
                                         lambda key, **v: self.say(key, lang, **v)))

    @staticmethod
    def _beside(work, what: str, done=lambda: None) -> None:
        """Read from the LMS beside the launch, not in its way (the services are optional)."""
        async def run():
            try:
                await work
            except Exception as e:
                log.warning('lti: %s not read: %s', what, e)
            finally:
                done()
        tornado.ioloop.IOLoop.current().spawn_callback(run)

    def _picker(self, identity, reg, claims) -> None:
        if not allowed(identity, Action.MANAGE, Area.COURSE):
            self.refuse(f'adding rosgate to a course is for teachers; {identity.name} is {identity.role} here', 403)
            return
        ticket = secrets.token_urlsafe(24)
        self.lti.picks.put(ticket, (reg, claims))
        options = [('ide', 'Block IDE'), ('teleop', 'Teleop (drive a robot)'), ('class', 'Class view (teacher)')]
        examples = sorted(p.stem for p in self.lti.examples_dir.glob('*.json') if p.stem != 'index')
        options += [(f'example:{e}', f'IDE with the example {e}') for e in examples]
        options += [(f'exercise:{e.id}', f'Exercise "{e.title}" (graded: a gradebook column)') for e in self._exercises()]
        radios = ''.join(f'<p><label><input type="radio" name="pick" value="{html.escape(v)}"{" checked" if i == 0 else ""}>'
                         f' {html.escape(t)}</label></p>' for i, (v, t) in enumerate(options))
        self.page('rosgate: choose an activity',
                  f'<h1>Add rosgate to the course</h1><form method="post" action="/lti/deeplink">'
                  f'<input type="hidden" name="ticket" value="{ticket}">{radios}'
                  '<p><label>The IDE\'s program as <select name="as"><option value="blocks">blocks</option>'
                  '<option value="python">Python text</option><option value="javascript">JavaScript text</option>'
                  '</select></label> (a text exercise: a new text program, or the example written as text)</p>'
                  '<p><label>Station (optional, e.g. s03) <input name="station"></label></p>'
                  '<p><label>Title <input name="title" value="Robot lab"></label></p>'
                  '<button type="submit" id="add">Add to the course</button></form>')

    def _exercises(self) -> list:
        if self.lti.exercises is None:
            return []
        found, problems = self.lti.exercises.all()
        for problem in problems:
            log.warning('lti: exercise not offered: %s', problem)
        return found


def landed_page(landing: str, ticket: str, identity, nonce: str, say) -> str:
    """Signed in: on to the landing page once the browser shows it kept the session cookie; a
    browser that refused it (Safari inside an iframe) is offered the same launch in a new window.
    `say(key, **values)`: the page's words (escaped) in the launch's language."""
    target = html.escape(landing)
    link = f'<a href="{target}">{target}</a>'
    state = say('lti.signed.in', name=identity.name, role=say(f'role.{identity.role}')).replace('{page}', link, 1)
    return (f'<p id="state">{state}</p>'
            f'<p id="blocked" hidden>{say("lti.blocked")} '
            f'<a id="newwin" href="/lti/resume?ticket={ticket}" target="_blank" rel="opener">'
            f'{say("lti.newwin")}</a></p>'
            f'<script nonce="{nonce}">fetch("/whoami",{{credentials:"same-origin",cache:"no-store"}})'
            f'.then(r=>r.ok?location.replace({json.dumps(landing)}):Promise.reject())'
            '.catch(()=>{document.getElementById("blocked").hidden=false})</script>')


class ResumeHandler(LtiPage):
    def get(self) -> None:
        found = self.lti.resume.take(self.get_argument('ticket', ''))
        if found is None:
            raise tornado.web.HTTPError(400, f'this link is used or more than {RESUME_TTL:g} s old: launch again '
                                             'from the course')
        identity, landing = found
        begin_session(self, self.lti.policy, identity, 'lti')
        self.redirect(landing, status=303)


class DeepLinkHandler(LtiPage):
    def post(self) -> None:
        check_origin(self, self.lti.policy)   # the picker is this gateway's own page
        found = self.lti.picks.take(self.get_argument('ticket', ''))
        if found is None:
            raise tornado.web.HTTPError(400, 'this choice was already sent, or waited too long: add the activity '
                                             'again from the course')
        reg, claims = found
        arg = self.get_argument
        item = deep_link_item(arg('pick', 'ide'), arg('as', 'blocks'), arg('station', ''), arg('title', ''),
                              self.lti.exercises, base_url(self))   # a Refusal (400) for a bad pick
        token = lti.deep_linking_response(self.lti.config, reg, claims, [item])
        settings = claims[lti.DL_CLAIM + 'deep_linking_settings']
        self.auto_post(settings['deep_link_return_url'], {'JWT': token}, 'Sending your choice to the course…')


class JwksHandler(tornado.web.RequestHandler):
    def initialize(self, lti_: Lti) -> None:
        self.lti = lti_

    def get(self) -> None:
        self.set_header('Content-Type', 'application/json')
        self.set_header('Cache-Control', 'max-age=300')
        self.finish(json.dumps(self.lti.config.jwks()))
