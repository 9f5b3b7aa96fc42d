"""LTI 1.3: who the LMS says launched, and whether to believe it.

``LtiConfig.load(path)`` reads PyLTI1p3's tool configuration JSON: issuer -> one registration or a
list of them (several client ids of one platform), each with ``client_id``, ``auth_login_url``
(the platform's OIDC authorization endpoint), ``key_set_url`` (its JWKS) or an inline
``key_set``, ``deployment_ids``, and the tool's own ``private_key_file`` (relative to the file;
none: one kept in the data directory, made at first start). ``auth_token_url`` is the platform's
token endpoint for LTI Advantage's services (scores: ``grades``; the roster: ``roster``), and
``memberships_urls`` (optional) the courses whose roster is read at start; ``auth_audience`` is
accepted and not needed. ``{}`` is a file with no platform yet: platforms then register through
LTI Dynamic Registration (``lti_dynamic``), whose registrations join these (``add``); one without a
deployment id takes any deployment of its own client id.

``check_launch`` judges an id_token with PyJWT: RS256 against the platform's key, iss, aud (and
azp when aud lists several), exp and iat with ``LEEWAY`` seconds of skew, the nonce this browser's
login was given, the deployment, message type and version. Each refusal is a ``LaunchError``
whose message says what was wrong (shown to the person; nobody is signed in).

Roles: membership (context) roles decide — Instructor, TeachingAssistant, ContentDeveloper,
Administrator (and their sub-roles) are ``admin``, Learner ``operator``, any other ``viewer``;
institution and system roles count only when the launch carries no membership role (Canvas
sends students institution roles too). A person is keyed by issuer and ``sub``.
"""

from __future__ import annotations

import base64
import hashlib
import json
import secrets
import time
from dataclasses import dataclass
from pathlib import Path

import jwt
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric import rsa

from ..settings import data_dir
from .tokens import Identity

LEEWAY = 60   # s of clock skew allowed on exp and iat
MAX_AGE = 3600   # s: an id_token issued longer ago than this is refused, whatever its exp
CLAIM = 'https://purl.imsglobal.org/spec/lti/claim/'
DL_CLAIM = 'https://purl.imsglobal.org/spec/lti-dl/claim/'
RESOURCE_LINK, DEEP_LINKING = 'LtiResourceLinkRequest', 'LtiDeepLinkingRequest'
ADMIN_ROLES = frozenset({'Instructor', 'TeachingAssistant', 'ContentDeveloper', 'Administrator'})
INSTITUTION_ADMIN = frozenset({'Instructor', 'Faculty', 'Administrator', 'SysAdmin'})
INSTITUTION_LEARNER = frozenset({'Student', 'Learner'})


class LaunchError(Exception):
    """A launch refused; the message says why and is safe to show."""


@dataclass(frozen=True)
class Registration:
    issuer: str
    client_id: str
    auth_login_url: str
    key_set_url: str | None
    key_set: dict | None
    deployment_ids: tuple[str, ...]
    auth_token_url: str | None = None   # the platform's OAuth 2 token endpoint (AGS, NRPS)
    memberships_urls: tuple[str, ...] = ()   # courses whose roster (NRPS) is read at start


def _key_id(public_key) -> str:
    der = public_key.public_bytes(serialization.Encoding.DER, serialization.PublicFormat.SubjectPublicKeyInfo)
    return base64.urlsafe_b64encode(hashlib.sha256(der).digest()[:16]).decode().rstrip('=')


def _load_private(path: Path):
    return serialization.load_pem_private_key(path.read_bytes(), password=None)


def tool_key(path: Path | None = None):
    """The tool's own RSA key: the given file, or one in the data directory made once (0600)."""
    if path is not None:
        return _load_private(path)
    path = data_dir('lti_private.pem')
    if path.is_file():
        return _load_private(path)
    key = rsa.generate_private_key(public_exponent=65537, key_size=2048)
    path.parent.mkdir(parents=True, exist_ok=True)
    pem = key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                            serialization.NoEncryption())
    tmp = path.with_suffix('.tmp')
    tmp.touch(mode=0o600)
    tmp.write_bytes(pem)
    tmp.replace(path)
    return key


class LtiConfig:
    def __init__(self, registrations: list[Registration], keys: dict, path: str = ''):
        self.registrations = registrations
        self.keys = keys              # kid -> private key (the tool's; signs deep-linking responses)
        self.path = path

    @classmethod
    def load(cls, path: str | Path) -> LtiConfig:
        path = Path(path)
        data = json.loads(path.read_text())
        if not isinstance(data, dict):   # {}: no platform yet (one registers by LTI Dynamic Registration)
            raise ValueError(f'{path}: expected an object of issuer -> registration(s)')
        regs, keys, key_files = [], {}, set()
        for issuer, items in data.items():
            for i, item in enumerate(items if isinstance(items, list) else [items]):
                where = f'{path}: {issuer}[{i}]'
                if not isinstance(item, dict):
                    raise ValueError(f'{where}: expected an object')
                for field in ('client_id', 'auth_login_url'):
                    if not item.get(field):
                        raise ValueError(f'{where}: {field} is required')
                if not item.get('key_set_url') and not item.get('key_set'):
                    raise ValueError(f'{where}: give key_set_url (the platform\'s JWKS) or key_set')
                deployments = item.get('deployment_ids') or []
                if not isinstance(deployments, list) or not deployments:
                    raise ValueError(f'{where}: deployment_ids is a list of the platform\'s deployment ids')
                regs.append(Registration(issuer, str(item['client_id']), item['auth_login_url'],
                                         item.get('key_set_url'), item.get('key_set'),
                                         tuple(str(d) for d in deployments), item.get('auth_token_url'),
                                         tuple(str(u) for u in item.get('memberships_urls') or ())))
                if item.get('private_key_file'):
                    key_files.add(path.parent / item['private_key_file'])
        try:
            private = [_load_private(f) for f in sorted(key_files)] or [tool_key()]
        except (OSError, ValueError) as e:
            raise ValueError(f'{path}: tool private key: {e}') from None
        for key in private:
            keys[_key_id(key.public_key())] = key
        return cls(regs, keys, str(path))

    def add(self, reg: Registration) -> None:
        """A registration made by LTI Dynamic Registration (``lti_dynamic``), in place of an earlier one
        of the same platform and client id."""
        self.registrations = [r for r in self.registrations if (r.issuer, r.client_id) != (reg.issuer, reg.client_id)]
        self.registrations.append(reg)

    def find(self, issuer: str, client_id: str | None = None) -> Registration | None:
        for reg in self.registrations:
            if reg.issuer == issuer and (client_id is None or reg.client_id == client_id):
                return reg
        return None

    def jwks(self) -> dict:
        """The tool's public keys, published at /lti/jwks."""
        out = []
        for kid, key in self.keys.items():
            jwk = json.loads(jwt.algorithms.RSAAlgorithm.to_jwk(key.public_key()))
            out.append({**jwk, 'kid': kid, 'alg': 'RS256', 'use': 'sig'})
        return {'keys': out}

    def signing_key(self) -> tuple[str, object]:
        kid = next(iter(self.keys))
        return kid, self.keys[kid]


def unverified(id_token: str) -> tuple[dict, dict]:
    """(header, claims) read without checking anything: to know which platform and key to ask."""
    try:
        return jwt.get_unverified_header(id_token), jwt.decode(id_token, options={'verify_signature': False})
    except jwt.PyJWTError as e:
        raise LaunchError(f'the id_token is not a JWT: {e}') from None


def registration_for(config: LtiConfig, claims: dict) -> Registration:
    iss = claims.get('iss')
    if not isinstance(iss, str) or config.find(iss) is None:
        raise LaunchError(f'the platform {str(iss)[:200]!r} is not registered with this tool (--lti)')
    aud = claims.get('aud')
    auds = [aud] if isinstance(aud, str) else aud if isinstance(aud, list) else []
    if len(auds) > 1:
        client = claims.get('azp')
        if client not in auds:
            raise LaunchError('the id_token names several audiences and no azp among them')
        auds = [client]
    for client_id in auds:
        reg = config.find(iss, str(client_id))
        if reg is not None:
            return reg
    raise LaunchError(f'the id_token is for another tool (aud {str(aud)[:200]!r}, not a client id registered '
                      f'for {iss})')


def check_launch(id_token: str, key, reg: Registration, nonce: str, now: float | None = None) -> dict:
    """The id_token's claims once everything about them holds; LaunchError otherwise."""
    try:
        claims = jwt.decode(id_token, key, algorithms=['RS256'], audience=reg.client_id, issuer=reg.issuer,
                            leeway=LEEWAY, options={'require': ['exp', 'iat', 'iss', 'aud', 'sub', 'nonce']})
    except jwt.ExpiredSignatureError:
        raise LaunchError('the id_token has expired (exp is past); launch again from the course') from None
    except jwt.ImmatureSignatureError:
        raise LaunchError('the id_token is issued in the future (iat): check the clocks') from None
    except jwt.InvalidSignatureError:
        raise LaunchError('the id_token\'s signature does not match the platform\'s key') from None
    except jwt.InvalidAudienceError:
        raise LaunchError('the id_token is for another tool (aud)') from None
    except jwt.PyJWTError as e:
        raise LaunchError(f'the id_token is not valid: {e}') from None
    now = time.time() if now is None else now
    if claims['iat'] < now - MAX_AGE:
        raise LaunchError('the id_token was issued too long ago (iat)')
    if claims.get('nonce') != nonce:
        raise LaunchError('the id_token\'s nonce is not the one this sign-in was given (a replayed launch?)')
    if claims.get(CLAIM + 'version') != '1.3.0':
        raise LaunchError(f'LTI version {str(claims.get(CLAIM + "version"))[:20]!r} is not 1.3.0')
    kind = claims.get(CLAIM + 'message_type')
    if kind not in (RESOURCE_LINK, DEEP_LINKING):
        raise LaunchError(f'message type {str(kind)[:60]!r} is not one this tool takes '
                          f'({RESOURCE_LINK}, {DEEP_LINKING})')
    deployment = claims.get(CLAIM + 'deployment_id')
    if not isinstance(deployment, str) or (reg.deployment_ids and deployment not in reg.deployment_ids):
        raise LaunchError(f'deployment {str(deployment)[:100]!r} of {reg.issuer} is not registered with this tool')
    if kind == RESOURCE_LINK and not isinstance((claims.get(CLAIM + 'resource_link') or {}).get('id'), str):
        raise LaunchError('a resource link launch without resource_link.id')
    if kind == DEEP_LINKING and not (claims.get(DL_CLAIM + 'deep_linking_settings') or {}).get('deep_link_return_url'):
        raise LaunchError('a deep linking request without deep_link_return_url')
    return claims


def _role_name(uri: str) -> tuple[str, str]:
    """(kind, name) of an LTI role: membership, institution, system, or membership for the bare
    short names LTI 1.3 still allows."""
    if '/membership' in uri or '/' not in uri:
        kind = 'membership'
    elif '/institution/' in uri:
        kind = 'institution'
    else:
        kind = 'system'
    return kind, uri.rsplit('#', 1)[-1].rsplit('/', 1)[-1]


def role_of(roles) -> str:
    names = {'membership': set(), 'institution': set(), 'system': set()}
    for uri in roles if isinstance(roles, list) else []:
        if isinstance(uri, str):
            kind, name = _role_name(uri)
            names[kind].add(name)
    if names['membership']:
        m = names['membership']
        return 'admin' if m & ADMIN_ROLES else 'operator' if 'Learner' in m else 'viewer'
    other = names['institution'] | names['system']
    return 'admin' if other & INSTITUTION_ADMIN else 'operator' if other & INSTITUTION_LEARNER else 'viewer'


def identity_of(claims: dict) -> Identity:
    """The person: named as the LMS names them, keyed by issuer and subject."""
    name = (claims.get('name') or ' '.join(p for p in (claims.get('given_name'), claims.get('family_name')) if p)
            or claims.get('email') or claims['sub'])
    key = 'lti-' + hashlib.sha256(f'{claims["iss"]}\n{claims["sub"]}'.encode()).hexdigest()[:24]
    return Identity(str(name)[:100], role_of(claims.get(CLAIM + 'roles')), key)


def deep_linking_response(config: LtiConfig, reg: Registration, claims: dict, items: list[dict],
                          now: float | None = None) -> str:
    """The signed LtiDeepLinkingResponse JWT for the content items the teacher picked."""
    now = int(time.time() if now is None else now)
    settings = claims.get(DL_CLAIM + 'deep_linking_settings') or {}
    payload = {
        'iss': reg.client_id, 'aud': [reg.issuer], 'iat': now, 'exp': now + 600,
        'nonce': secrets.token_urlsafe(16),
        CLAIM + 'message_type': 'LtiDeepLinkingResponse',
        CLAIM + 'version': '1.3.0',
        CLAIM + 'deployment_id': claims[CLAIM + 'deployment_id'],
        DL_CLAIM + 'content_items': items,
    }
    if 'data' in settings:
        payload[DL_CLAIM + 'data'] = settings['data']
    kid, key = config.signing_key()
    return jwt.encode(payload, key, algorithm='RS256', headers={'kid': kid})
