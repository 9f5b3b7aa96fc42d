"""LTI roles and identities (auth.lti), and the tool configuration file as PyLTI1p3 writes it."""

from __future__ import annotations

import json

import pytest

from gateway.auth import lti

M = 'http://purl.imsglobal.org/vocab/lis/v2/membership#'
I = 'http://purl.imsglobal.org/vocab/lis/v2/institution/person#'
S = 'http://purl.imsglobal.org/vocab/lis/v2/system/person#'


@pytest.mark.parametrize('roles, role', [
    ([M + 'Learner'], 'operator'),
    ([M + 'Instructor'], 'admin'),
    (['http://purl.imsglobal.org/vocab/lis/v2/membership/Instructor#TeachingAssistant'], 'admin'),
    ([M + 'ContentDeveloper'], 'admin'),
    ([M + 'Administrator'], 'admin'),
    ([M + 'Mentor'], 'viewer'),
    ([M + 'Learner', I + 'Administrator', S + 'Administrator'], 'operator'),   # membership decides
    ([M + 'Learner', M + 'Instructor'], 'admin'),
    (['Learner'], 'operator'), (['Instructor'], 'admin'),                     # short names
    ([I + 'Instructor'], 'admin'), ([I + 'Student'], 'operator'), ([I + 'Guest'], 'viewer'),
    ([], 'viewer'), (None, 'viewer'), ('Instructor', 'viewer'),
])
def test_roles(roles, role):
    assert lti.role_of(roles) == role


def test_a_person_is_keyed_by_issuer_and_subject():
    a = lti.identity_of({'iss': 'https://moodle.school', 'sub': '42', 'name': 'Ann Lee', lti.CLAIM + 'roles': []})
    b = lti.identity_of({'iss': 'https://moodle.school', 'sub': '42', 'given_name': 'Ann', lti.CLAIM + 'roles': []})
    c = lti.identity_of({'iss': 'https://canvas.school', 'sub': '42', 'name': 'Ann Lee', lti.CLAIM + 'roles': []})
    assert a.name == 'Ann Lee' and b.name == 'Ann'
    assert a.owner == b.owner != c.owner and a.owner.startswith('lti-')


def test_tool_configuration(tmp_path):
    path = tmp_path / 'tool.json'
    path.write_text(json.dumps({'https://a.example': [{'client_id': 'c1', 'auth_login_url': 'https://a.example/auth',
                                                       'key_set_url': 'https://a.example/jwks',
                                                       'deployment_ids': ['d1', 'd2']},
                                                      {'client_id': 'c2', 'auth_login_url': 'https://a.example/auth',
                                                       'key_set_url': 'https://a.example/jwks',
                                                       'deployment_ids': ['d3']}]}))
    config = lti.LtiConfig.load(path)
    assert [r.client_id for r in config.registrations] == ['c1', 'c2']
    assert config.find('https://a.example', 'c2').deployment_ids == ('d3',)
    assert config.jwks()['keys'][0]['kty'] == 'RSA'
    path.write_text(json.dumps({'https://a.example': {'client_id': 'c1', 'auth_login_url': 'x'}}))
    with pytest.raises(ValueError, match='key_set_url'):
        lti.LtiConfig.load(path)
