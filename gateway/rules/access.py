"""One access rule: may someone read, write, call or own this.

``may(policy, who, action, name)`` answers for every path the same way: the websocket's ops
(``Policy.check``), the HTTP APIs, video streams, the history, OPC UA, recordings (what they take,
as whom), playback, runs and bookings. ``who`` is an ``Identity`` (an HTTP caller, an OPC UA user),
a session or sender (its ``attrs['role']``), or None: the gateway asking for itself, or a caller
when auth is off; then the name globs alone decide. ``action``: subscribe, read (the gateway's
read-only services), publish, call, send_goal, advertise_service, advertise_action, param,
programs; ``name``: the topic, service or action, or None to ask about the role alone. It returns
None (allowed) or the reason, which every path words the same.

After the role and the globs, the *keepers* answer: parts that keep names of their own, each a
``(who, action, name) -> reason | None`` (``KEEPERS`` names them; ``rules.compose`` hands them to
the policy). A recording, a playback, the history or a stream asks ``may`` as the person it is for,
so what a keeper refuses a person over the websocket it refuses through every other door.

``owns(who, theirs)``: the one "admin or owner": an admin, or the thing is theirs; with auth off
(``who`` None) everyone, as every request is an admin's then (``acts_as_admin``). ``is_admin(who)``: a signed-in admin
(quotas, seeing everyone's), which nobody is with auth off. ``person_of(who)``: the person a
session, sender or Identity is (``rules.stations``' key). The role sets are named once here.
"""

from __future__ import annotations

from .stations import person_of as _person_of_request
from .tokens import ROLES

ADMINS = ('admin',)
OPERATORS = ('operator', 'admin')     # those who may change things: drive, run, record, book
EVERYONE = ROLES                      # every role may look

# Who keeps which names (each a keeper the policy asks after the role and the globs):
KEEPERS = {
    'runs': 'a run\'s /rosgate/runs/ID/output and /state: its starter\'s and the admins\' (runs.supervisor)',
    'reports': 'NS/rosgate/program: stamped by the gateway; read by its station\'s person and admins (rules.reports)',
    'stations': 'a station\'s services, actions and topics: its holder\'s and owner\'s, with --exclusive-control '
                '(rules.lease.Lease.name_refusal)',
    'attempts': 'a live exercise attempt\'s station: the attempter\'s, and no service that moves the robot '
                'without driving it (exercises.checker)',
}


def role_of(who) -> str | None:
    """The role of an Identity, a session or a sender."""
    attrs = getattr(who, 'attrs', None)
    return attrs.get('role') if attrs is not None else getattr(who, 'role', None)


def person_of(who) -> str | None:
    """The person of a session or sender (its ``attrs['person']``) or of an Identity (its name's)."""
    attrs = getattr(who, 'attrs', None)
    if attrs is not None:
        return attrs.get('person')
    return _person_of_request(who, {}) if who is not None else None


def may(policy, who, action: str, name: str | None = None) -> str | None:
    """None when ``who`` may ``action`` ``name`` under ``policy``, else why not."""
    return policy.refusal(who, action, name)


def owns(who, theirs: bool) -> bool:
    """An admin, or the thing is theirs; everyone when auth is off (``who`` None)."""
    return acts_as_admin(who) or theirs


def acts_as_admin(who) -> bool:
    """An admin, or anyone when auth is off (every request is an admin's then)."""
    return who is None or role_of(who) == 'admin'


def is_admin(who) -> bool:
    """A signed-in admin (nobody when auth is off)."""
    return who is not None and role_of(who) == 'admin'
