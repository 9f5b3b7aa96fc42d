"""Names as resources of the one decision, in-process: ``Access.decide(who, action, Name(name))``
answers every cell of test_rule_tables' role × action × name table as the websocket's words say it
(``may``, the status a refused op gets), with the HTTP status of its ``Unauthorized`` (401 for a
client not signed in, 403 otherwise); ``LIST`` (rosapi's listings, Foxglove's graph) follows the
name globs for everyone."""

from __future__ import annotations

import pytest

from gateway.rules.access import Action, Name, Unauthorized, may
from tests.rules.test_rule_tables import FLEET, GLOBS, MAY, MAY_GLOBS, people
from tests.support.auth import tokens_toml
from tests.support.inproc import InProcess


@pytest.fixture(scope='module')
def tokens(tmp_path_factory):
    path = tmp_path_factory.mktemp('names') / 'tokens.toml'
    path.write_text(tokens_toml())
    return str(path)


def check_decide(gw, table: dict, who: dict) -> list[str]:
    wrong = []
    for (action, name, col), want in table.items():
        name = None if name == '-' else name
        said = may(gw.policy, who[col], action, name)
        got = gw.policy.access.decide(who[col], Action(action), Name(name))
        status = None if want == 'ok' else 401 if want == 'unauth' else 403
        if (got is None) != (said is None) or (got is not None and (
                not isinstance(got, Unauthorized) or got.message != said or got.status != status)):
            wrong.append(f'decide({col}, {action}, {name}): {got!r}, the websocket says {said!r} ({want})')
    return wrong


async def test_decide_about_names_as_the_websocket_words_them(tokens):
    async with InProcess(*FLEET, '--auth', tokens) as gw:
        wrong = check_decide(gw, MAY, await people(gw))
    assert not wrong, '\n'.join(wrong)


async def test_decide_follows_the_name_globs_and_lists_what_they_allow(tokens):
    async with InProcess(*FLEET, '--auth', tokens, *GLOBS) as gw:
        who = await people(gw)
        wrong = check_decide(gw, MAY_GLOBS, who)
        access = gw.policy.access
        for col in ('alice', 'vera', 'nobody', 'gateway'):
            listed = {(kind, n): access.decide(who[col], Action.LIST, Name(n, kind)) is None
                      for kind, n in (('topics', '/s01/turtle1/pose'), ('topics', '/turtle1/pose'),
                                      ('services', '/rosapi/topics'), ('services', '/s01/turtlesim/set_parameters'))}
            if listed != {('topics', '/s01/turtle1/pose'): True, ('topics', '/turtle1/pose'): False,
                          ('services', '/rosapi/topics'): True, ('services', '/s01/turtlesim/set_parameters'): False}:
                wrong.append(f'{col} lists {listed}')
    assert not wrong, '\n'.join(wrong)
