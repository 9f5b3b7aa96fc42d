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

Parameters: a node's own ``<node>/set_parameters`` (and ``set_parameters_atomically``) and rosapi's
``set_param``/``delete_param`` need the ``param`` permission (an admin's), which an operator (a
student) has only for the nodes of a station she owns (``station_param``); a node's
``get_parameters``, ``list_parameters``, ``describe_parameters`` and ``get_parameter_types`` are
reads (a viewer's too). Judged by the service's name, as ROS 2 names them (``parameter_service``).

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


PARAM_READS = frozenset({'list_parameters', 'get_parameters', 'get_parameter_types', 'describe_parameters'})
PARAM_WRITES = frozenset({'set_parameters', 'set_parameters_atomically'})


def parameter_service(name: str) -> str | None:
    """'read' or 'param' for a node's parameter service (``/s01/turtlesim/set_parameters``), else None."""
    leaf = name.rpartition('/')[2]
    return 'param' if leaf in PARAM_WRITES else 'read' if leaf in PARAM_READS else None


def parameter_node(name: str) -> str:
    """The node whose parameters a name reaches: its service (``/s01/turtlesim/set_parameters``) or
    rosapi's parameter name (``/s01/turtlesim:background_r``) -> ``/s01/turtlesim``."""
    node, sep, _ = name.partition(':')
    if not sep:
        node = name.rpartition('/')[0]
    return node if node.startswith('/') else '/' + node


def station_param(stations, who, name: str) -> str | None:
    """None when ``who`` owns the station the node of ``name`` is in, else why not (an operator
    changes the parameters of her own station's nodes only)."""
    node = parameter_node(name)
    top = '/' + node.strip('/').split('/')[0]
    if stations is not None and top in stations.stations() and stations.is_owner(who, top):
        return None
    return (f'{node} is not in a station of yours: role {role_of(who)} may change parameters only of its own '
            'station\'s nodes (press "Claim a robot"), an admin any')


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
