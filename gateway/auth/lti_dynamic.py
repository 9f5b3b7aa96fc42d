"""LTI Dynamic Registration 1.0 (IMS): a platform registers rosgate from one URL, no values copied.

The admin of this gateway makes a registration URL (``make_link``: one use, ``LINK_TTL`` s, kept
in the store as a digest so that any gateway of a fleet can take it) and pastes it into the LMS
(Moodle 4.x: Site administration > Plugins > External tool > Manage tools > "Tool URL..."; Canvas:
Admin > Developer Keys > + LTI Registration). The platform opens it with ``openid_configuration``
(its OpenID configuration's URL) and ``registration_token``; the tool (``web.lti_setup``) takes the
link (``take_link``: once), fetches the configuration (``check_platform``: its issuer on the same
host as that URL, https except on loopback, the endpoints it needs), POSTs ``tool_registration``
(the OpenID client metadata with the LTI tool configuration claim: the resource link and deep
linking messages, the AGS and NRPS scopes the platform offers, its JWKS URL) with the token as
a bearer, and keeps what the platform answers (``registration_of``: client_id, the deployment
it made, the platform's issuer and endpoints) in ``lti_platforms``, where launches find it beside
the --lti file's (``LtiConfig.add``; ``load`` at start and on a launch from a platform not known yet).

A registration without a deployment id (Canvas makes the deployment when the tool is installed)
takes launches of any deployment of its client id: the client id is this registration's alone.
"""

from __future__ import annotations

import hashlib
import json
import secrets
import time
from urllib.parse import urlsplit

import sqlalchemy as sa

from ..store import METADATA
from .lti import LtiConfig, Registration

LINK_TTL = 3600.0   # s a registration URL stays good
TOOL_CONFIG = 'https://purl.imsglobal.org/spec/lti-tool-configuration'
PLATFORM_CONFIG = 'https://purl.imsglobal.org/spec/lti-platform-configuration'
SCOPES = ('https://purl.imsglobal.org/spec/lti-ags/scope/lineitem',
          'https://purl.imsglobal.org/spec/lti-ags/scope/lineitem.readonly',
          'https://purl.imsglobal.org/spec/lti-ags/scope/result.readonly',
          'https://purl.imsglobal.org/spec/lti-ags/scope/score',
          'https://purl.imsglobal.org/spec/lti-nrps/scope/contextmembership.readonly')
LOOPBACK = ('127.0.0.1', 'localhost', '::1')

LINKS = sa.Table(
    'lti_registration_links', METADATA,
    sa.Column('digest', sa.String(64), primary_key=True),   # sha256 of the link's ticket
    sa.Column('made_by', sa.String(100), nullable=False),
    sa.Column('expires', sa.Float, nullable=False),
    sa.Column('used', sa.Float, nullable=True),
)
PLATFORMS = sa.Table(
    'lti_platforms', METADATA,
    sa.Column('issuer', sa.String(255), primary_key=True),
    sa.Column('client_id', sa.String(255), primary_key=True),
    sa.Column('deployment_ids', sa.String(1000), nullable=False),   # JSON list (empty: any of this client)
    sa.Column('auth_login_url', sa.String(1000), nullable=False),
    sa.Column('key_set_url', sa.String(1000), nullable=False),
    sa.Column('auth_token_url', sa.String(1000), nullable=True),
    sa.Column('product', sa.String(100), nullable=False),
    sa.Column('scopes', sa.String(2000), nullable=False),
    sa.Column('registered', sa.Float, nullable=False),
    sa.Column('registered_by', sa.String(100), nullable=False),
)


class RegistrationError(Exception):
    """A registration refused or failed; the message says why (shown to the admin)."""


def _digest(ticket: str) -> str:
    return hashlib.sha256(ticket.encode()).hexdigest()


def make_link(conn: sa.Connection, made_by: str, now: float | None = None) -> str:
    """A new registration ticket (kept as its digest); the caller builds the URL."""
    now = time.time() if now is None else now
    ticket = secrets.token_urlsafe(24)
    conn.execute(LINKS.delete().where(LINKS.c.expires < now))
    conn.execute(LINKS.insert().values(digest=_digest(ticket), made_by=made_by[:100], expires=now + LINK_TTL))
    return ticket


def take_link(conn: sa.Connection, ticket: str, now: float | None = None) -> str | None:
    """Who made the ticket, once: None when it is unknown, used or expired."""
    now = time.time() if now is None else now
    digest = _digest(ticket)
    taken = conn.execute(LINKS.update().where(LINKS.c.digest == digest, LINKS.c.used.is_(None),
                                              LINKS.c.expires >= now).values(used=now)).rowcount
    if taken != 1:
        return None
    return conn.execute(sa.select(LINKS.c.made_by).where(LINKS.c.digest == digest)).scalar()


def secure_url(url: str, what: str) -> str:
    parts = urlsplit(str(url))
    if not parts.hostname or (parts.scheme != 'https' and not (parts.scheme == 'http' and parts.hostname in LOOPBACK)):
        raise RegistrationError(f'{what} is not an https URL: {str(url)[:200]!r}')
    return str(url)


def check_platform(config_url: str, config) -> dict:
    """The platform's OpenID configuration, checked: the endpoints a registration needs, and its
    issuer on the host its configuration came from (a configuration cannot speak for another)."""
    if not isinstance(config, dict):
        raise RegistrationError('the platform\'s OpenID configuration is not a JSON object')
    for key in ('issuer', 'authorization_endpoint', 'jwks_uri', 'registration_endpoint'):
        if not isinstance(config.get(key), str) or not config[key]:
            raise RegistrationError(f'the platform\'s OpenID configuration has no {key}')
        secure_url(config[key], key)
    if urlsplit(config['issuer']).hostname != urlsplit(config_url).hostname:
        raise RegistrationError(f'the issuer {config["issuer"][:200]} is not on the host of the configuration '
                                f'({urlsplit(config_url).hostname})')
    if config.get('token_endpoint') is not None:
        secure_url(config['token_endpoint'], 'token_endpoint')
    return config


def tool_registration(base: str, platform: dict, name: str = 'rosgate') -> dict:
    """The client registration rosgate POSTs: OpenID client metadata and the LTI tool configuration."""
    offered = platform.get('scopes_supported')
    scopes = [s for s in SCOPES if not isinstance(offered, list) or s in offered]
    return {
        'application_type': 'web',
        'response_types': ['id_token'],
        'grant_types': ['implicit', 'client_credentials'],
        'initiate_login_uri': f'{base}/lti/login',
        'redirect_uris': [f'{base}/lti/launch'],
        'client_name': name,
        'jwks_uri': f'{base}/lti/jwks',
        'token_endpoint_auth_method': 'private_key_jwt',
        'scope': ' '.join(scopes),
        TOOL_CONFIG: {
            'domain': urlsplit(base).netloc,
            'target_link_uri': f'{base}/',
            'description': 'Robots in the browser: block and text programs, teleop, exercises graded on the robot',
            'claims': ['iss', 'sub', 'name', 'given_name', 'family_name', 'email'],
            'messages': [
                {'type': 'LtiResourceLinkRequest', 'target_link_uri': f'{base}/', 'label': name},
                {'type': 'LtiDeepLinkingRequest', 'target_link_uri': f'{base}/lti/launch', 'label': name,
                 'placements': ['link_selection', 'assignment_selection']},
            ],
            'https://canvas.instructure.com/lti/privacy_level': 'public',   # names, for the class view
        },
    }


def registration_of(platform: dict, answer) -> tuple[Registration, str, str]:
    """(the Registration, the platform's product, the scopes granted) from the platform's answer."""
    if not isinstance(answer, dict) or not isinstance(answer.get('client_id'), (str, int)) \
            or not str(answer['client_id']):
        raise RegistrationError('the platform\'s answer has no client_id')
    tool = answer.get(TOOL_CONFIG) if isinstance(answer.get(TOOL_CONFIG), dict) else {}
    deployment = tool.get('deployment_id')
    product = (platform.get(PLATFORM_CONFIG) or {}).get('product_family_code', '')
    reg = Registration(platform['issuer'], str(answer['client_id']), platform['authorization_endpoint'],
                       platform['jwks_uri'], None, (str(deployment),) if deployment not in (None, '') else (),
                       platform.get('token_endpoint'))
    return reg, str(product)[:100], str(answer.get('scope', ''))[:2000]


def save(conn: sa.Connection, reg: Registration, product: str, scopes: str, by: str) -> None:
    row = dict(issuer=reg.issuer, client_id=reg.client_id, deployment_ids=json.dumps(list(reg.deployment_ids)),
               auth_login_url=reg.auth_login_url, key_set_url=reg.key_set_url, auth_token_url=reg.auth_token_url,
               product=product, scopes=scopes, registered=time.time(), registered_by=by[:100])
    conn.execute(PLATFORMS.delete().where(PLATFORMS.c.issuer == reg.issuer, PLATFORMS.c.client_id == reg.client_id))
    conn.execute(PLATFORMS.insert().values(**row))


def load(conn: sa.Connection, config: LtiConfig) -> int:
    """Every registration made here into the configuration; how many."""
    rows = conn.execute(sa.select(PLATFORMS)).mappings().all()
    for r in rows:
        config.add(Registration(r['issuer'], r['client_id'], r['auth_login_url'], r['key_set_url'], None,
                                tuple(json.loads(r['deployment_ids'])), r['auth_token_url']))
    return len(rows)


def registered(conn: sa.Connection) -> list[dict]:
    return [dict(r) for r in conn.execute(sa.select(PLATFORMS).order_by(PLATFORMS.c.registered)).mappings()]
