"""The access rule and the driver lease as tables, in-process (tests/support/inproc.py: the real
Gateway, sim backend and rules, clients fed frames as the websocket feeds them; no socket, no
process): role × action × resource for ``may`` and ``owns``, and lease state × question × who for
the lease (a command through the publish door, the control topic's take, take-if-free, release and
stop, and the Lease's refusals for a playback and a run). Each lease case gets a gateway of its own
(some 40 ms of CPU) whose state is made through the ops a page sends. ``decide`` (the HTTP areas) as
area × action × who, with --auth on and off, on a thing of the asker's own and of another's. The black-box tests
(test_access.py, test_lease_per_robot.py, test_stations.py, the browser tests) keep checking the
same rules through real sockets and pages; these tables say every case at once, and which one a
change moved."""

from __future__ import annotations

import pytest

from gateway.rules.access import NOBODY, Action, Area, StationGrants, acts_as_admin, decide, is_admin, may, owns
from gateway.rules.stations import person
from gateway.auth.tokens import Identity
from tests.support.auth import TOKENS, tokens_toml
from tests.support.inproc import InProcess, settle
from tests.support.wait import until

TWIST = 'geometry_msgs/msg/Twist'
CMD = '/s01/turtle1/cmd_vel'
FLEET = ('--robot', 'turtlesim', '--fleet', '3', '--exclusive-control')


@pytest.fixture(scope='module')
def tokens(tmp_path_factory):
    path = tmp_path_factory.mktemp('tables') / 'tokens.toml'
    path.write_text(tokens_toml())
    return str(path)


def twist(x: float) -> dict:
    return {'linear': {'x': x, 'y': 0.0, 'z': 0.0}, 'angular': {'x': 0.0, 'y': 0.0, 'z': 0.0}}


def grid(text: str, keys: int = 2) -> dict[tuple[str, str, str], str]:
    """A table as the eye reads it: a header ending in its columns' names, then rows of ``keys``
    words and one cell per column; {(*key, column): cell}."""
    lines = [line.split() for line in text.strip().splitlines() if line.strip()]
    head, rows = lines[0], lines[1:]
    out = {}
    for row in rows:
        cols = head[len(head) - (len(row) - keys):]
        assert len(cols) == len(row) - keys, row
        out.update({(*row[:keys], col): cell for col, cell in zip(cols, row[keys:])})
    return out


# --- may(): role × action × resource ------------------------------------------------------------

# alice (operator) owns /s01; bob (operator) owns nothing; vera is a viewer; "nobody" connected
# without signing in; "gateway" is who=None (the gateway asking for itself). ok: allowed; else
# the words of the refusal (held: a station's actions and services that move or reset its robot
# are its holder's, as its velocity commands are under the lease).
MAY = grid('''
action/resource                              alice     bob       teacher   vera      nobody    gateway
subscribe         /s01/turtle1/pose          ok        ok        ok        ok        unauth    ok
publish           /s01/turtle1/cmd_vel       ok        ok        ok        role      unauth    ok
publish           /rosgate/driver            globs     globs     globs     role      unauth    globs
publish           /rosgate/control           ok        ok        ok        role      unauth    ok
call              /rosapi/topics             ok        ok        ok        ok        unauth    ok
call              /rosapi/set_param          ok        ok        ok        role      unauth    ok
call              /s01/turtlesim/set_parameters ok     station   ok        role      unauth    ok
call              /s02/turtlesim/set_parameters station station  ok        role      unauth    ok
call              /s01/turtlesim/get_parameters ok     ok        ok        ok        unauth    ok
param             /s01/turtlesim:background_r ok       station   ok        role      unauth    ok
send_goal         /s01/turtle1/rotate_absolute ok      held      ok        role      unauth    ok
advertise_service /my_service                role      role      ok        role      unauth    ok
advertise_action  /my_action                 role      role      ok        role      unauth    ok
programs          -                          role      role      ok        role      unauth    ok
''')
MAY_WORDS = {'role': 'may not', 'unauth': 'not authenticated', 'station': 'is not in a station of yours',
             'globs': 'is not allowed for', 'held': "is alice's station"}

# the name globs decide for everyone, the gateway included
GLOBS = ("--topics-glob", "['/s[0-9][0-9]/*', '/rosgate/*']", "--services-glob", "['/rosapi/*', '/s[0-9][0-9]/fleet/*']")
MAY_GLOBS = grid('''
action/resource                              teacher   gateway
subscribe         /s01/turtle1/pose          ok        ok
subscribe         /turtle1/pose              globs     globs
call              /rosapi/topics             ok        ok
call              /s01/turtlesim/set_parameters globs  globs
''')


async def people(gw) -> dict:
    who = {name: gw.client(TOKENS[token]) for name, token in
           (('alice', 'operator'), ('bob', 'operator2'), ('teacher', 'admin'), ('vera', 'viewer'))}
    who['nobody'] = gw.client()
    who['alice'].send({'op': 'call_service', 'service': '/s01/fleet/claim', 'type': 'std_srvs/srv/Trigger',
                       'id': 'claim'})
    assert (await who['alice'].reply('claim'))['values']['success']
    return {name: c.session for name, c in who.items()} | {'gateway': None}


def check_may(gw, table: dict, who: dict) -> list[str]:
    wrong = []
    for (action, name, col), want in table.items():
        why = may(gw.policy, who[col], action, None if name == '-' else name)
        if (want == 'ok') != (why is None) or (why is not None and MAY_WORDS[want] not in why):
            wrong.append(f'may({col}, {action}, {name}): {why!r}, the table says {want}')
    return wrong


async def test_may_by_role_action_and_resource(tokens):
    async with InProcess(*FLEET, '--auth', tokens) as gw:
        wrong = check_may(gw, MAY, await people(gw))
    assert not wrong, '\n'.join(wrong)


async def test_may_follows_the_name_globs_for_everyone(tokens):
    async with InProcess(*FLEET, '--auth', tokens, *GLOBS) as gw:
        wrong = check_may(gw, MAY_GLOBS, await people(gw))
    assert not wrong, '\n'.join(wrong)


async def test_owns_and_admins(tokens):
    """The one "admin or owner": an admin, or the thing is theirs; with auth off (who None) everyone."""
    async with InProcess(*FLEET, '--auth', tokens) as gw:
        who = await people(gw)
        table = {(col, theirs): owns(who[col], theirs) for col in ('alice', 'teacher', 'vera', 'gateway')
                 for theirs in (True, False)}
        assert table == {('alice', True): True, ('alice', False): False, ('teacher', True): True,
                         ('teacher', False): True, ('vera', True): True, ('vera', False): False,
                         ('gateway', True): True, ('gateway', False): True}
        assert [acts_as_admin(who[c]) for c in ('alice', 'teacher', 'vera', 'gateway')] == [False, True, False, True]
        assert [is_admin(who[c]) for c in ('alice', 'teacher', 'vera', 'gateway')] == [False, True, False, False]


# --- the lease: state × question × who, on /s01 ---------------------------------------------------

# States, made through ops: free (nobody owns /s01); owned (alice claimed it); held (alice's page A1
# drove it); others (bob claimed it); walked (bob drove the unclaimed station); stopped (held, then
# the teacher's Stop); released (held, then the teacher's Release: alice is barred).
# Who: A1 (alice's page), A2 (another page of alice's), bob, the teacher (admin), vera (viewer).
# Outcomes: ok (a command reached the robot), holds / nothing (after a take: the lease is, is not
# that client's), free / held / halted (the lease after a release or a stop), or a refusal:
ACTORS = ('A1', 'A2', 'bob', 'teacher', 'vera')
LEASE = grid('''
state     question      A1        A2        bob       teacher   vera
free      move          ok        ok        ok        ok        role
owned     move          ok        ok        theirs    theirs    role
held      move          ok        ok        driving   driving   role
others    move          theirs    theirs    ok        theirs    role
walked    move          driving   driving   ok        driving   role
stopped   move          stopped   stopped   stopped   stopped   role
released  move          released  released  ok        ok        role

free      zero          ok        ok        ok        ok        role
owned     zero          ok        ok        ok        ok        role
held      zero          ok        ok        driving   driving   role
others    zero          ok        ok        ok        ok        role
walked    zero          driving   driving   ok        driving   role
stopped   zero          ok        ok        ok        ok        role
released  zero          ok        ok        ok        ok        role

free      take          holds     holds     holds     holds     role
owned     take          holds     holds     theirs    holds     role
held      take          holds     holds     theirs    holds     role
others    take          theirs    theirs    holds     holds     role
walked    take          driving   driving   holds     holds     role
stopped   take          holds     holds     stopped   holds     role
released  take          released  released  holds     holds     role

free      take-if-free  holds     holds     holds     holds     role
owned     take-if-free  holds     holds     nothing   nothing   role
held      take-if-free  holds     nothing   nothing   nothing   role
others    take-if-free  nothing   nothing   holds     nothing   role
walked    take-if-free  nothing   nothing   holds     nothing   role
stopped   take-if-free  nothing   nothing   nothing   nothing   role
released  take-if-free  nothing   nothing   holds     holds     role

free      release       free      free      free      free      role
owned     release       free      free      free      free      role
held      release       free      admin     admin     free      role
others    release       free      free      free      free      role
walked    release       admin     admin     free      free      role
stopped   release       halted    halted    halted    free      role
released  release       free      free      free      free      role

free      stop          admin     admin     admin     halted    role
held      stop          admin     admin     admin     halted    role
stopped   stop          admin     admin     admin     halted    role
''')
LEASE_WORDS = {'role': 'may not publish to', 'theirs': "'s station", 'driving': 'is driving /s01',
               'stopped': 'stopped /s01', 'released': 'released /s01: it is not your robot', 'admin': 'only an admin',
               'lease': 'holds the driver lease'}

# The Lease's refusals for what a person starts besides a page's commands: a playback into /s01
# (topic_refusal) and a robot-side run on /s01 (run_refusal, with the starter's role).
REFUSALS = grid('''
state     refusal       alice     bob       teacher
free      playback      ok        ok        ok
owned     playback      ok        theirs    theirs
held      playback      driving   driving   driving
others    playback      theirs    ok        theirs
walked    playback      driving   driving   driving
stopped   playback      stopped   stopped   stopped
released  playback      released  ok        ok

free      run           ok        ok        ok
owned     run           ok        theirs    ok
held      run           ok        theirs    ok
others    run           theirs    ok        ok
walked    run           lease     ok        ok
stopped   run           stopped   stopped   ok
released  run           released  ok        ok
''')


class Lab:
    """A gateway of its own for one case, its clients, and the state the case starts from."""

    def __init__(self, gw):
        self.gw = gw
        self.c = {'A1': gw.client(TOKENS['operator']), 'A2': gw.client(TOKENS['operator']),
                  'bob': gw.client(TOKENS['operator2']), 'teacher': gw.client(TOKENS['admin']),
                  'vera': gw.client(TOKENS['viewer'])}
        self.heard: list[dict] = []
        self._ids = 0
        gw.backend.subscribe(CMD, TWIST, self.heard.append)

    def _id(self) -> str:
        self._ids += 1
        return f'op{self._ids}'

    async def ok(self, who: str, op: dict) -> dict:
        """An op that must pass: its reply, if it has one."""
        id = op['id'] = self._id()
        self.c[who].send(op)
        await settle()
        errors = [m for m in self.c[who].statuses('error') if m.get('id') == id]
        assert not errors, (who, op, errors)
        if op['op'] == 'call_service':
            reply = await self.c[who].reply(id)
            assert reply['result'] and reply['values'].get('success', True), (who, op, reply)
            return reply
        return {}

    async def tried(self, who: str, op: dict) -> str | None:
        """An op whose refusal is the outcome: the refusal's words, or None."""
        id = op['id'] = self._id()
        self.c[who].send(op)
        await settle()
        return next((m['msg'] for m in self.c[who].statuses('error') if m.get('id') == id), None)

    def drive(self, x: float = 0.5) -> dict:
        return {'op': 'publish', 'topic': CMD, 'type': TWIST, 'msg': twist(x)}

    @staticmethod
    def control(words: str) -> dict:
        return {'op': 'publish', 'topic': '/rosgate/control', 'type': 'std_msgs/msg/String', 'msg': {'data': words}}

    @staticmethod
    def call(service: str) -> dict:
        return {'op': 'call_service', 'service': service, 'type': 'std_srvs/srv/Trigger'}

    @property
    def holder(self):
        return self.gw.lease.holders.get('/s01')

    def holder_name(self) -> str | None:
        return next((n for n, c in self.c.items() if c.session is self.holder), None)

    async def arrange(self, state: str) -> None:
        stations, lease = self.gw.stations, self.gw.lease
        alice, bob = person(self.c['A1'].session), person(self.c['bob'].session)
        if state in ('owned', 'held', 'stopped', 'released'):
            await self.ok('A1', self.call('/s01/fleet/claim'))
        if state in ('held', 'stopped', 'released'):
            await self.ok('A1', self.drive())
            assert self.holder_name() == 'A1'
        if state == 'others':
            await self.ok('bob', self.call('/s01/fleet/claim'))
        if state == 'walked':
            await self.ok('bob', self.drive())
            assert self.holder_name() == 'bob' and stations.owner('/s01') is None
        if state == 'stopped':
            await self.ok('teacher', self.control('stop /s01'))
            assert '/s01' in lease.halted and self.holder is None
        if state == 'released':
            await self.ok('teacher', self.call('/s01/fleet/release'))
            assert stations.is_barred('/s01', alice) and stations.owner('/s01') is None and self.holder is None
        owner = stations.owner('/s01')
        assert (owner.person if owner else None) == {'owned': alice, 'held': alice, 'stopped': alice,
                                                      'others': bob}.get(state), (state, owner)
        self.heard.clear()

    async def ask(self, question: str, who: str) -> str:
        """What the question gives for ``who``: an outcome word of the table, or the refusal's words."""
        if question in ('move', 'zero'):
            why = await self.tried(who, self.drive(0.5 if question == 'move' else 0.0))
            if why is not None:
                return why
            await until(lambda: self.heard, 5, what=f'{who}\'s {question} at the robot')
            return 'ok'
        words = {'take': 'take /s01', 'take-if-free': 'take-if-free /s01', 'release': 'release /s01',
                 'stop': 'stop /s01'}[question]
        why = await self.tried(who, self.control(words))
        if why is not None:
            return why
        if question.startswith('take'):
            return 'holds' if self.holder is self.c[who].session else 'nothing'
        return 'halted' if '/s01' in self.gw.lease.halted else 'held' if self.holder is not None else 'free'


def matches(got: str, want: str, words: dict) -> bool:
    return got == want if want not in words else words[want] in got


STATES = ('free', 'owned', 'held', 'others', 'walked', 'stopped', 'released')


@pytest.mark.parametrize('state', STATES)
async def test_the_lease_by_state_question_and_who(state, tokens):
    wrong = []
    for (row, question, who), want in LEASE.items():
        if row != state:
            continue
        async with InProcess(*FLEET, '--auth', tokens) as gw:
            lab = Lab(gw)
            await lab.arrange(state)
            got = await lab.ask(question, who)
            if not matches(got, want, LEASE_WORDS):
                wrong.append(f'{state:9} {question:13} {who:8}: {got!r}, the table says {want}')
    assert not wrong, '\n'.join(wrong)


@pytest.mark.parametrize('state', STATES)
async def test_the_leases_refusals_for_a_playback_and_a_run(state, tokens):
    async with InProcess(*FLEET, '--auth', tokens) as gw:
        lab = Lab(gw)
        await lab.arrange(state)
        keys = {'alice': person(lab.c['A1'].session), 'bob': person(lab.c['bob'].session),
                'teacher': person(lab.c['teacher'].session)}
        roles = {'alice': 'operator', 'bob': 'operator', 'teacher': 'admin'}
        wrong = []
        for (row, refusal, who), want in REFUSALS.items():
            if row != state:
                continue
            if refusal == 'playback':
                why = gw.lease.topic_refusal(keys[who], CMD, TWIST)
            else:
                why = gw.lease.run_refusal(keys[who], roles[who], '/s01')
            if not matches('ok' if why is None else why, want, LEASE_WORDS):
                wrong.append(f'{state:9} {refusal:9} {who:8}: {why!r}, the table says {want}')
    assert not wrong, '\n'.join(wrong)


# --- with auth off: people are browsers, anyone may take over, stop and release --------------------

# the gateway-wide group of one turtle (/turtle1/cmd_vel); A1 and A2 are two tabs of one browser,
# B another browser, S a script (no browser id: a person of its own while connected)
OPEN = grid('''
state     question      A1        A2        B         S
free      move          ok        ok        ok        ok
held      move          ok        ok        driving   driving
held      take          holds     holds     holds     holds
held      release       free      free      free      free
held      stop          halted    halted    halted    halted
''')
OPEN_WORDS = {'driving': 'is driving (exclusive control)'}


async def test_the_lease_with_auth_off_by_browser():
    wrong = []
    for (state, question, who), want in OPEN.items():
        async with InProcess('--robot', 'turtlesim', '--exclusive-control') as gw:
            c = {'A1': gw.client(browser='browser-aaaa-1111'), 'A2': gw.client(browser='browser-aaaa-1111'),
                 'B': gw.client(browser='browser-bbbb-2222'), 'S': gw.client()}
            heard = []
            gw.backend.subscribe('/turtle1/cmd_vel', TWIST, heard.append)

            def publish(name, topic, type, msg):
                c[name].send({'op': 'publish', 'topic': topic, 'type': type, 'msg': msg, 'id': f'{name}-{len(heard)}'})

            if state == 'held':
                publish('A1', '/turtle1/cmd_vel', TWIST, twist(0.5))
                await until(lambda: heard, 5)
                assert gw.lease.holder is c['A1'].session
                heard.clear()
            n = len(c[who].statuses('error'))
            if question == 'move':
                publish(who, '/turtle1/cmd_vel', TWIST, twist(0.5))
            else:
                publish(who, '/rosgate/control', 'std_msgs/msg/String', {'data': f'{question} /'})
            await settle()
            errors = c[who].statuses('error')[n:]
            if errors:
                got = errors[0]['msg']
            elif question == 'move':
                await until(lambda: heard, 5)
                got = 'ok'
            elif question == 'take':
                got = 'holds' if gw.lease.holder is c[who].session else 'nothing'
            else:
                got = 'halted' if '/' in gw.lease.halted else 'held' if gw.lease.holder is not None else 'free'
            if not matches(got, want, OPEN_WORDS):
                wrong.append(f'{state:6} {question:8} {who:3}: {got!r}, the table says {want}')
    assert not wrong, '\n'.join(wrong)


# --- decide(): area × action × who, with --auth on and off, owner and not -------------------------

# Written from what each HTTP door answered before it asked ``decide`` (caller(roles=...), is_admin,
# acts_as_admin, owns): ok, 403 (role or owner) or 401 (--auth on, no valid token). open: a caller
# with --auth off (every request an admin's then, but a per-person limit holds: EXEMPT is nobody's).
AREAS = grid('''
area/action           viewer  operator  admin  nobody  open
programs    see       ok      ok        ok     401     ok
programs    change    403     ok        ok     401     ok
programs    manage    403     403       ok     401     ok
runs        see       ok      ok        ok     401     ok
runs        change    403     ok        ok     401     ok
runs        manage    403     403       ok     401     ok
runs        exempt    403     403       ok     401     403
recordings  change    403     ok        ok     401     ok
recordings  manage    403     403       ok     401     ok
recordings  exempt    403     403       ok     401     403
bookings    see       ok      ok        ok     401     ok
bookings    change    403     ok        ok     401     ok
bookings    manage    403     403       ok     401     ok
bookings    exempt    403     403       ok     401     403
queue       see       ok      ok        ok     401     ok
queue       change    403     ok        ok     401     ok
people      see       403     403       ok     401     ok
exercises   see       ok      ok        ok     401     ok
exercises   change    403     403       ok     401     ok
attempts    change    ok      ok        ok     401     ok
attempts    manage    403     403       ok     401     ok
attempts    exempt    403     403       ok     401     403
roster      see       403     403       ok     401     ok
roster      change    403     403       ok     401     ok
class       see       403     403       ok     401     ok
course      manage    403     403       ok     401     403
blocks      see       ok      ok        ok     401     ok
blocks      change    403     403       ok     401     ok
history     see       ok      ok        ok     401     ok
video       see       ok      ok        ok     401     ok
gauges      see       ok      ok        ok     401     ok
packages    see       ok      ok        ok     401     ok
whoami      see       ok      ok        ok     401     ok
server      see       403     403       ok     401     ok
stations    manage    403     403       ok     401     ok
stations    exempt    403     403       ok     401     403
reports     manage    403     403       ok     401     ok
''')

# A thing of someone's: "mine" (the asker's own key for the area: its Identity's owner, or its
# person for bookings and stations), "other" (another's) or "none" (nobody's: started with --auth off).
OWNED = grid('''
area/action/whose            viewer  operator  admin  open
runs        see      mine    ok      ok        ok     ok
runs        see      other   403     403       ok     ok
runs        see      none    403     403       ok     ok
runs        change   mine    403     ok        ok     ok
runs        change   other   403     403       ok     ok
recordings  change   mine    403     ok        ok     ok
recordings  change   other   403     403       ok     ok
bookings    change   mine    ok      ok        ok     ok
bookings    change   other   403     403       ok     ok
attempts    see      mine    ok      ok        ok     ok
attempts    see      other   403     403       ok     ok
stations    see      mine    ok      ok        ok     ok
stations    see      other   403     403       ok     ok
''', keys=3)
WORDS = {('runs', 'change', 'viewer'): 'role viewer may not do this; it needs operator or admin',
         ('runs', 'manage', 'operator'): 'role operator may not do this; it needs admin',
         ('runs', 'see', 'nobody'): 'a token is required: sign in at /login or send Authorization: Bearer'}


def asker(col: str):
    if col == 'open':
        return None
    return NOBODY if col == 'nobody' else Identity(col.capitalize(), col)


def answer(why) -> str:
    return 'ok' if why is None else str(why.status)


def test_decide_by_area_action_and_role():
    wrong = [f'{area} {action} {col}: {answer(why)}, the table says {want}'
             for (area, action, col), want in AREAS.items()
             if answer(why := decide(asker(col), Action(action), Area(area))) != want]
    assert not wrong, '\n'.join(wrong)
    for (area, action, col), words in WORDS.items():
        assert decide(asker(col), Action(action), Area(area)).message == words


def test_decide_by_owner():
    wrong = []
    for (area, action, whose, col), want in OWNED.items():
        who = asker(col)
        key = None if who is None else who.owner if area not in ('bookings', 'stations') else f'user {who.owner}'
        owner = {'mine': key or 'someone', 'other': 'someone else', 'none': None}[whose]
        got = answer(decide(who, Action(action), Area(area), owner))
        if got != want:
            wrong.append(f'{area} {action} {whose}\'s {col}: {got}, the table says {want}')
    assert not wrong, '\n'.join(wrong)


async def test_decide_reads_a_session_as_its_identity(tokens):
    """A websocket session (its attrs) is asked as the Identity it signed in as; with --auth off
    the claims and the lease let anyone override, and nobody pass a stop."""
    async with InProcess(*FLEET, '--auth', tokens) as gw:
        who = await people(gw)
        for col, role in (('alice', 'operator'), ('teacher', 'admin'), ('vera', 'viewer')):
            for (area, action, c), want in AREAS.items():
                if c == role:
                    assert answer(decide(who[col], Action(action), Area(area))) == want, (col, area, action)
        assert answer(decide(who['alice'], Action.SEE, Area.STATIONS, person(who['alice']))) == 'ok'
        assert answer(decide(who['vera'], Action.SEE, Area.STATIONS, person(who['alice']))) == '403'
        grants = StationGrants(auth=True)
        assert [grants.overrides(who[c]) for c in ('alice', 'teacher', 'vera')] == [False, True, False]
        assert [grants.exempt(who[c]) for c in ('alice', 'teacher', 'vera')] == [False, True, False]
    off = StationGrants(auth=False)
    assert (off.overrides('viewer'), off.overrides(None), off.exempt('admin'), off.exempt(None)) == (True, True, False, False)
