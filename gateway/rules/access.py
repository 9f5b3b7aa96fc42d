"""One access rule: may someone read, write, call, own or manage this.

Two questions, both answered here and nowhere else (tests/security/test_access_is_one.py walks the
code for a role compared anywhere else):

- Names (the websocket's verbs): ``Access.decide(who, action, Name(name))`` (the gateway's one
  ``Access``, ``policy.access``: its name globs, keepers and stations; ``may(policy, who, action,
  name)`` and ``Access.refusal`` are its words) answers for every path the same way: the websocket's
  and Foxglove's ops (``Policy.check``), their listings (``LIST``: the globs), rosapi's parameter
  writes, topic statistics, video streams, the history, OPC UA, recordings (what they take, as
  whom), playback. ``who`` is an ``Identity`` (an HTTP caller, an OPC UA user), a
  session or sender (its ``attrs['role']``), or None: the gateway asking for itself, or a caller
  when auth is off; then the name globs alone decide. ``action``: subscribe, read (the gateway's
  read-only services), publish, call, send_goal, advertise_service, advertise_action, param,
  programs, list; ``name``: the topic, service or action, or None to ask about the role alone. It
  returns None (allowed) or an ``Unauthorized`` whose words every path gives the same.
- The driver lease's commands: ``StationGrants.verdict`` reads the role and asks the lease's table
  (``rules.leasetable``).
- Areas (the HTTP APIs, the stations, a program's report): ``decide(who, action, area, owner)``
  answers from ``TABLE`` (which role may SEE, CHANGE, MANAGE -- everyone's, or on someone else's
  behalf -- or be EXEMPT from a per-person limit in each ``Area``) and the owner rule: a thing of
  someone else's (``owner`` given, not the asker's) needs MANAGE; a thing of the asker's own may be
  changed by the roles of ``OWN`` where it names the area; with --auth off every thing is
  everyone's. ``who`` None is a caller with --auth off,
  who may everything but EXEMPT (a per-person limit holds for everyone then, as it always did);
  ``NOBODY`` is a caller with --auth on and no valid token (401). It returns None or an
  ``Unauthorized`` (a ``Refusal``: the HTTP status and the words), which the HTTP handlers'
  ``@authorized`` (``web.api``) raise as they are.

After the role and the globs, the *keepers* answer: parts that keep names of their own, each a
``(who, action, name) -> reason | None`` (``KEEPERS`` names them; ``rules.compose`` hands them to
the policy). A recording, a playback, the history or a stream asks ``may`` as the person it is for,
so what a keeper refuses a person over the websocket it refuses through every other door.

Parameters: a node's own ``<node>/set_parameters`` (and ``set_parameters_atomically``) and rosapi's
``set_param``/``delete_param`` need the ``param`` permission (an admin's), which an operator (a
student) has only for the nodes of a station she owns (``station_param``); a node's
``get_parameters``, ``list_parameters``, ``describe_parameters`` and ``get_parameter_types`` are
reads (a viewer's too). Judged by the service's name, as ROS 2 names them (``parameter_service``).

``owns(who, theirs)``, ``acts_as_admin(who)`` and ``is_admin(who)`` are ``decide`` asked about no
area in particular (kept for the keepers' tables). ``person_of(who)``: the person a session, sender
or Identity is (``rules.stations``' key). The role sets are named once here.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum, StrEnum
from fnmatch import fnmatchcase
from functools import lru_cache

from .errors import Refusal
from .names import ACTION_KINDS, CONTROL_TOPIC, OWN_PREFIX, WRITING_ROSAPI, action_of
from .leasetable import Command, LeaseFacts, Verdict, Who, verdict
from .stations import person_of as _person_of_request
from ..auth.tokens import ROLES, Role

ADMINS = (Role.ADMIN.value,)
OPERATORS = (Role.OPERATOR.value, Role.ADMIN.value)     # those who may change things: drive, run, record, book
EVERYONE = ROLES                                        # every role may look
GATEWAY_ROLE = 'gateway'   # the role of what the gateway publishes itself (stops): passes the lease, never moves
TOKEN_NEEDED = 'a token is required: sign in at /login or send Authorization: Bearer'
NOT_AUTHENTICATED = ('not authenticated: send {"op": "auth", "token": ...} first '
                     '(or connect with ?token=, an Authorization: Bearer header, or the session cookie of /login)')
PERMISSIONS = {
    'viewer': frozenset({'subscribe', 'read'}),
    'operator': frozenset({'subscribe', 'read', 'publish', 'call', 'send_goal'}),
    'admin': frozenset({'subscribe', 'read', 'publish', 'call', 'send_goal',
                        'advertise_service', 'advertise_action', 'param', 'programs'}),
}
VERBS = {'subscribe': 'subscribe to', 'read': 'call', 'publish': 'publish to', 'call': 'call',
         'send_goal': 'send goals to', 'advertise_service': 'advertise', 'advertise_action': 'advertise',
         'param': 'change parameters through', 'programs': 'use'}

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


RANKS = ('viewer', 'operator', 'admin')


def lowered(role: str, asked) -> str:
    """``role``, or the lower one a connection asks for (``?as=operator``: a page running a program
    from another person's share link lends it no admin rights, ide/js/run/foreign.js); never higher."""
    want = asked[-1].decode('ascii', 'replace') if isinstance(asked, list) and asked else asked
    if isinstance(want, str) and want in RANKS and role in RANKS and RANKS.index(want) < RANKS.index(role):
        return want
    return role


def role_refusal(who, need: str, name: str | None, stations, rosapi_write: bool = False) -> str | None:
    """The websocket's role rule (``Policy.refusal`` with --auth): None, or why ``who``'s role may not
    do what ``need`` names (``PERMISSIONS``) to ``name``; an operator changes the parameters of her own
    station's nodes (``station_param``; rosapi's writes, ``rosapi_write``, are judged again by the
    parameter's name)."""
    role = role_of(who)
    if role is None:
        return NOT_AUTHENTICATED
    if need == 'param' and role in OPERATORS and need not in PERMISSIONS.get(role, ()) and name is not None:
        return None if rosapi_write else station_param(stations, who, name)
    if need not in PERMISSIONS.get(role, ()):
        return f'role {role} may not {VERBS[need]} {name}' if name is not None else \
            f'role {role} may not {VERBS[need]} this'
    return None


def may(policy, who, action: str, name: str | None = None) -> str | None:
    """None when ``who`` may ``action`` ``name`` under ``policy``, else why not."""
    return policy.access.refusal(who, action, name)


class Action(StrEnum):
    # names (the websocket's verbs, asked about a ``Name``; equal to the words the doors used)
    SUBSCRIBE = 'subscribe'
    READ = 'read'           # the gateway's read-only services, a node's parameter getters
    PUBLISH = 'publish'
    CALL = 'call'
    SEND_GOAL = 'send_goal'
    ADVERTISE_SERVICE = 'advertise_service'
    ADVERTISE_ACTION = 'advertise_action'
    PARAM = 'param'         # change parameters
    PROGRAMS = 'programs'
    LIST = 'list'           # see a name in the graph's listings (rosapi, Foxglove's graph): the globs
    # areas and owned things
    SEE = 'see'
    CHANGE = 'change'
    MANAGE = 'manage'       # everyone's, or on someone else's behalf
    EXEMPT = 'exempt'       # past a per-person limit (or a teacher's stop or bar on a station)


class Area(StrEnum):
    """What an HTTP API (or a part of the rules) is about, as Jupyter Server's ``AUTH_RESOURCE``."""
    PROGRAMS = 'programs'
    RUNS = 'runs'
    RECORDINGS = 'recordings'
    BOOKINGS = 'bookings'
    QUEUE = 'queue'
    PEOPLE = 'people'
    EXERCISES = 'exercises'
    ATTEMPTS = 'attempts'
    ROSTER = 'roster'
    CLASS = 'class'
    COURSE = 'course'           # adding rosgate to an LMS course, registering an LMS
    BLOCKS = 'blocks'
    HISTORY = 'history'
    VIDEO = 'video'
    GAUGES = 'gauges'
    PACKAGES = 'packages'
    SHARES = 'shares'
    DESCRIPTION = 'description'
    WHOAMI = 'whoami'
    SERVER = 'server'           # server paths and the database's address
    STATIONS = 'stations'       # the robots under claims and the driver lease
    REPORTS = 'reports'         # a station's program report (NS/rosgate/program)


class Standing(Enum):
    OPEN = 'anyone (--auth off)'
    NOBODY = 'not signed in'


class Whose(Enum):
    AREA = 'the area as a whole'     # decide's owner when the question is about no thing in particular


OPEN, NOBODY, AREA = Standing.OPEN, Standing.NOBODY, Whose.AREA
V, O, A = Role.VIEWER, Role.OPERATOR, Role.ADMIN
_ALL = frozenset({OPEN, V, O, A})
_DOERS = frozenset({OPEN, O, A})        # operators: drive, run, record, book, save
_MANAGERS = frozenset({OPEN, A})        # an admin, or anyone with --auth off
_ADMIN = frozenset({A})                 # a signed-in admin only: nobody with --auth off
_NONE: frozenset = frozenset()

# area: (SEE, CHANGE, MANAGE, EXEMPT) -- who may, by role; OPEN: a caller with --auth off.
TABLE: dict[Area, tuple[frozenset, frozenset, frozenset, frozenset]] = {
    Area.PROGRAMS:    (_ALL, _DOERS, _MANAGERS, _NONE),       # MANAGE: another's space, the shared one
    Area.RUNS:        (_ALL, _DOERS, _MANAGERS, _ADMIN),      # EXEMPT: --max-runs-per-person
    Area.RECORDINGS:  (_ALL, _DOERS, _MANAGERS, _ADMIN),      # EXEMPT: the per-person cap
    Area.BOOKINGS:    (_ALL, _DOERS, _MANAGERS, _ADMIN),      # MANAGE: others', past slots, "for"; EXEMPT: limits
    Area.QUEUE:       (_ALL, _DOERS, _MANAGERS, _NONE),
    Area.PEOPLE:      (_MANAGERS, _MANAGERS, _MANAGERS, _NONE),
    Area.EXERCISES:   (_ALL, _MANAGERS, _MANAGERS, _NONE),
    Area.ATTEMPTS:    (_ALL, _ALL, _MANAGERS, _ADMIN),        # CHANGE: start or stop one (a viewer too)
    Area.ROSTER:      (_MANAGERS, _MANAGERS, _MANAGERS, _NONE),
    Area.CLASS:       (_MANAGERS, _MANAGERS, _MANAGERS, _NONE),
    Area.COURSE:      (_ADMIN, _ADMIN, _ADMIN, _NONE),       # an LMS launch or sign-in always has a person
    Area.BLOCKS:      (_ALL, _MANAGERS, _MANAGERS, _NONE),     # CHANGE: publish blocks to the class
    Area.HISTORY:     (_ALL, _NONE, _NONE, _NONE),
    Area.VIDEO:       (_ALL, _NONE, _NONE, _NONE),
    Area.GAUGES:      (_ALL, _NONE, _NONE, _NONE),
    Area.PACKAGES:    (_ALL, _NONE, _NONE, _NONE),
    Area.SHARES:      (_ALL, _ALL, _NONE, _NONE),
    Area.DESCRIPTION: (_ALL, _NONE, _NONE, _NONE),
    Area.WHOAMI:      (_ALL, _NONE, _NONE, _NONE),
    Area.SERVER:      (_MANAGERS, _NONE, _NONE, _NONE),       # where files and the database are
    Area.STATIONS:    (_ALL, _DOERS, _MANAGERS, _ADMIN),      # MANAGE: take over, release others'; EXEMPT: past a stop
    Area.REPORTS:     (_ALL, _DOERS, _MANAGERS, _NONE),       # MANAGE: another station's report
}
COLUMN = {Action.SEE: 0, Action.CHANGE: 1, Action.MANAGE: 2, Action.EXEMPT: 3}
# On a thing of one's own, these may CHANGE it beyond the table's CHANGE (cancel a booking made for
# them), and which key says whose a thing is: the person (``rules.stations``' key,
# 'user ada'), else the Identity's owner ('ada', 'lti-…').
OWN: dict[Area, frozenset] = {Area.BOOKINGS: _ALL}
BY_PERSON = frozenset({Area.BOOKINGS, Area.QUEUE, Area.STATIONS, Area.REPORTS})


@dataclass(frozen=True, slots=True)
class Name:
    """A topic, service, action or parameter as a resource of ``Access.decide`` (None: the role
    alone is asked about); ``kind`` for ``LIST``: topics, services, actions or params."""
    name: str | None
    kind: str | None = None


class Access:
    """The one decision with this gateway's facts: ``decide`` answers for the areas (``TABLE``)
    and for names: with --auth the role (``role_refusal``), then rosbridge's name globs
    (``ACTION_KINDS``; an action's hidden names follow its actions glob; nobody publishes on the
    gateway's own topics but its control topic), then the keepers (never for the gateway's own).
    ``who`` None: the gateway asking for itself, or any caller with --auth off."""

    def __init__(self, globs: dict[str, tuple[str, ...] | None], *, auth: bool = False, stations=None,
                 reads: Callable[[str], bool] = lambda name: False, keepers: tuple = ()):
        self.globs, self.auth, self.stations, self.reads, self.keepers = globs, auth, stations, reads, keepers

    def matches(self, kind: str, name: str) -> bool:
        globs = self.globs.get(kind)
        return globs is None or any(fnmatchcase(name, g) for g in globs)

    def allows(self, action: str, name: str) -> bool:
        if action == 'publish' and name.startswith(OWN_PREFIX) and name != CONTROL_TOPIC:
            return False   # the gateway's own announcements: only the gateway publishes there
        base = action_of(name)     # an action's hidden services and topics follow its actions glob too
        if base is not None and not self.matches('actions', base):
            return False
        return all(self.matches(kind, name) for kind in ACTION_KINDS[action])

    def visible(self, kind: str, name: str) -> bool:
        """LIST: kind is topics, services, actions or params."""
        if kind == 'topics':
            return self.matches('topics', name) and (self.matches('topics_pub', name) or self.matches('topics_sub', name))
        return self.matches(kind, name)

    def refusal(self, who, action: str, name: str | None) -> str | None:
        """The words of ``decide`` about a name: None, or why ``who`` may not ``action`` ``name``."""
        if self.auth and who is not None:
            need = permission(action, name, self.reads) if name is not None else action
            why = role_refusal(who, need, name, self.stations, name in WRITING_ROSAPI)
            if why is not None:
                return why
        if name is None:
            return None
        if not self.allows(action, name):
            return f'{name} is not allowed for {action} by this gateway'
        if who is not None and not is_gateway(who):   # nor from the gateway itself
            for keeper in self.keepers:
                why = keeper(who, action, name)
                if why is not None:
                    return why
        return None

    def decide(self, who, action: Action, resource, owner: str | None | Whose = AREA) -> Unauthorized | None:
        """None when ``who`` may ``action`` ``resource`` (a ``Name``, or an ``Area``: ``decide``), else why not."""
        if type(resource) is not Name:
            return decide(who, action, resource, owner)
        if action is Action.LIST:
            if self.visible(resource.kind, resource.name):
                return None
            why = f'{resource.name} is not listed by this gateway'
        else:
            why = self.refusal(who, action, resource.name)
            if why is None:
                return None
        return Unauthorized(401 if why is NOT_AUTHENTICATED else 403, why, actor(who), action, resource)


def permission(action: str, name: str, reads: Callable[[str], bool]) -> str:
    """The permission an action needs; calls of the gateway's own rosapi services (``reads``)
    are reads, except the parameter writes; a node's parameter services (``parameter_service``)
    are reads or parameter writes."""
    if action == 'call' and reads(name):
        return 'param' if name in WRITING_ROSAPI else 'read'
    if action == 'call':
        return parameter_service(name) or action
    return action


@dataclass(frozen=True, slots=True)
class Actor:
    """Who asks, as ``decide`` reads it: a role (None: not one of ``Role``, as the gateway's own),
    or a standing (OPEN, NOBODY); the keys things are owned by."""
    role: Role | Standing | None
    owner: str | None = None
    person: str | None = None

    @property
    def words(self) -> str:
        return f'role {self.role}' if isinstance(self.role, Role) else str(self.role.value if self.role else 'nobody')


class Unauthorized(Refusal):
    """``decide``'s answer when it refuses: the HTTP status (401 not signed in, 403 not allowed),
    the words, and what was asked (``area``: an ``Area``, or a ``Name`` asked of ``Access.decide``)."""

    def __init__(self, status: int, message: str, actor: Actor, action: Action, area: Area):
        super().__init__(status, message)
        self.actor, self.action, self.area = actor, action, area


def actor(who) -> Actor:
    """The one place a role is read: an Actor as it is, None (--auth off: OPEN), NOBODY, an
    Identity, a session or a sender (its attrs), or a bare role (a run's starter's)."""
    if isinstance(who, Actor):
        return who
    if who is None or who is OPEN:
        return Actor(OPEN)
    if who is NOBODY:
        return Actor(NOBODY)
    if isinstance(who, str):
        return as_role(who)
    role = role_of(who)
    owner = getattr(who, 'owner', None) if getattr(who, 'attrs', None) is None else None
    return Actor(Role(role) if role in ROLES else None, owner, person_of(who))


def as_role(role: str | None) -> Actor:
    """An actor of a bare role (a run's starter's, passed on): nobody's role when None."""
    return Actor(Role(role) if role in ROLES else None)


def decide(who, action: Action, area: Area, owner: str | None | Whose = AREA) -> Unauthorized | None:
    """None when ``who`` may ``action`` in ``area`` (on a thing of ``owner``'s, None: nobody's), else
    why not: the one access decision of the areas (module docstring)."""
    me = actor(who)
    if me.role is NOBODY:
        return Unauthorized(401, TOKEN_NEEDED, me, action, area)
    allowed = TABLE[area][COLUMN[action]]
    if owner is not AREA:
        mine = owner is not None and owner == (me.person if area in BY_PERSON else me.owner)
        if mine and me.role in OWN.get(area, _NONE):
            return None
        if not mine and me.role is not OPEN and me.role not in TABLE[area][COLUMN[Action.MANAGE]]:
            return Unauthorized(403, f'{me.words} may not do this to another\'s: only they or an admin may',
                                me, action, area)
    if me.role in allowed:
        return None
    needs = ' or '.join(r.value for r in Role if r in allowed) or 'no role'
    return Unauthorized(403, f'{me.words} may not do this; it needs {needs}', me, action, area)


def allowed(who, action: Action, area: Area, owner: str | None | Whose = AREA) -> bool:
    return decide(who, action, area, owner) is None


@dataclass(frozen=True, slots=True)
class StationGrants:
    """What the claims and the driver lease ask (``decide`` in ``Area.STATIONS``): whether ``who``
    (a session, a sender or a bare role) overrides another's claim or lease (MANAGE: an admin, or
    anyone with --auth off) or passes a teacher's stop or bar (EXEMPT: a signed-in admin)."""
    auth: bool

    def _who(self, who):
        if not self.auth:
            return None
        return as_role(who) if who is None or isinstance(who, str) else who

    def overrides(self, who) -> bool:
        return allowed(self._who(who), Action.MANAGE, Area.STATIONS)

    def exempt(self, who) -> bool:
        return allowed(self._who(who), Action.EXEMPT, Area.STATIONS)

    def who(self, who) -> Who:
        """``who`` as the lease's table reads it (by its role alone: remembered per role)."""
        if who is None or isinstance(who, str):
            return _station_who(self.auth, who, False)
        role = role_of(who)
        return _station_who(self.auth, role, role == GATEWAY_ROLE)

    def verdict(self, who, command: Command, facts: LeaseFacts) -> Verdict:
        """The lease's answer to ``who`` for ``command`` in a group of these facts (``rules.leasetable``)."""
        return verdict(self.who(who), command, facts)


@lru_cache(maxsize=64)
def _station_who(auth: bool, role: str | None, itself: bool) -> Who:
    grants = StationGrants(auth)
    return Who(grants.overrides(role), grants.exempt(role), itself)


def is_gateway(who) -> bool:
    """What the gateway sends itself (its stops, what the history keeps): not a person."""
    return role_of(who) == GATEWAY_ROLE


def owns(who, theirs: bool) -> bool:
    """An admin, or the thing is theirs; everyone when auth is off (``who`` None)."""
    return theirs or allowed(who, Action.MANAGE, Area.RUNS)


def acts_as_admin(who) -> bool:
    """An admin, or anyone when auth is off (every request is an admin's then)."""
    return allowed(who, Action.MANAGE, Area.RUNS)


def is_admin(who) -> bool:
    """A signed-in admin (nobody when auth is off)."""
    return allowed(who, Action.EXEMPT, Area.RUNS)
