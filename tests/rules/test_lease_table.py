"""The driver lease's table (gateway/rules/leasetable.py), in-process and pure: role × command ×
lease state, every case.

``ORACLE`` is the lease's branches as rules/lease.py wrote them before they asked the table (its
``require``, ``_command``, ``run_refusal``, ``topic_refusal`` and the claims' ``_may_release``),
transcribed over the facts; the table must answer every case as they did, for every role with
--auth on, anyone with --auth off, and the gateway itself. A row of the table changed (its answer,
or a condition) changes some case, and ``test_every_row_decides_a_case`` makes sure no row is dead
(one that decides nothing could be changed unseen). ``SENTENCES`` say the rules as a teacher would;
test_rule_tables.py and test_lease_per_robot.py keep checking the same rules through the real lease
and real clients."""

from __future__ import annotations

import itertools

import pytest

from gateway.rules.access import StationGrants
from gateway.rules.leasetable import (ROWS, TABLE, Command, Holder, LeaseFacts, Owning, Verdict, Who, first_row,
                                      verdict)

NONE, SELF, SAME, OTHER = Holder.NONE, Holder.SELF, Holder.SAME_PERSON, Holder.OTHER
FREE, MINE, OTHERS = Owning.FREE, Owning.MINE, Owning.OTHERS
V = Verdict


def oracle_drive(f: LeaseFacts, w: Who) -> Verdict:          # Lease.require
    if not f.command:
        return V.PASS
    if w.gateway and not f.moving:
        return V.PASS
    if f.holder is SELF:
        return V.PASS
    if f.halted:
        if not f.moving and f.holder is NONE:
            return V.PASS
        return V.STOPPED
    if f.settling is not NONE:
        if f.settling is SELF:
            return V.WAIT
        if not f.moving:
            return V.PASS
        return V.BEING_TAKEN
    if f.holder is SAME:
        return V.QUIET if f.moving else V.PASS
    if f.holder is NONE:
        if f.elsewhere:
            return V.ELSEWHERE
        barred = V.RELEASED if f.barred else V.ENDED if f.ended else None
        if barred is None and f.owner in (FREE, MINE):
            return V.GRANT
        if not f.moving:
            return V.PASS
        if barred is not None:
            return barred
        return V.OTHERS_STATION
    return V.OTHER_DRIVES


def oracle_control(verb: str, f: LeaseFacts, w: Who) -> Verdict:   # Lease._command
    mine = (f.owner is FREE and not f.barred) or f.owner is MINE
    if f.ended and verb.startswith('take') and not w.override:
        if verb == 'take-if-free':
            return V.NOTHING
        return V.ENDED
    if verb == 'take-if-free':
        if f.holder is NONE and mine and not f.halted and not f.elsewhere:
            return V.GRANT
        return V.NOTHING
    if verb == 'stop':
        return V.HALT if w.override else V.ADMIN_STOPS
    if verb == 'release':
        if f.holder is SELF:
            return V.FREE
        if w.override:
            return V.FREE_BY
        if f.holder is not NONE:
            return V.ADMIN_RELEASES
        return V.PASS
    if f.barred and not w.override:
        return V.RELEASED
    if f.halted and not mine and not w.exempt:
        return V.STOPPED_OWNER_ONLY
    if not mine and not w.override:
        return V.OTHERS_STATION
    if f.holder is NONE and f.elsewhere and not w.override:
        return V.ELSEWHERE
    if f.holder is SELF:
        return V.KEEP
    if f.holder is NONE:
        return V.TAKE_OVER if f.elsewhere else V.GRANT
    if f.holder is SAME:
        return V.SHARE
    if w.override:
        return V.TAKE_OVER
    return V.OTHER_DRIVES


def oracle_run(f: LeaseFacts, w: Who) -> Verdict:            # Lease.run_refusal
    admin = w.exempt
    if f.halted and not admin:
        return V.STOPPED_TAKE_FIRST
    if f.owner is FREE and f.barred and not admin:
        return V.RELEASED
    if f.owner is OTHERS and not w.override:
        return V.OTHERS_STATION
    if f.owner is FREE and f.ended and not admin:
        return V.ENDED
    if f.holder is not NONE and f.holder is not SAME and f.holder is not SELF and not w.override:
        return V.HOLDS_LEASE
    return V.PASS


def oracle_play(f: LeaseFacts, w: Who) -> Verdict:           # Lease.topic_refusal
    if not f.command:
        return V.PASS
    if f.halted:
        return V.STOPPED
    if f.holder is not NONE:
        return V.DRIVING
    if f.owner is FREE and f.barred:
        return V.RELEASED
    if f.owner is OTHERS:
        return V.OTHERS_STATION
    if f.owner is FREE and f.ended:
        return V.ENDED
    return V.PASS


ORACLE = {
    Command.DRIVE: oracle_drive,
    Command.TAKE: lambda f, w: oracle_control('take', f, w),
    Command.TAKE_IF_FREE: lambda f, w: oracle_control('take-if-free', f, w),
    Command.RELEASE: lambda f, w: oracle_control('release', f, w),
    Command.STOP: lambda f, w: oracle_control('stop', f, w),
    Command.RUN: oracle_run,
    Command.PLAY: oracle_play,
    Command.RELEASE_STATION: lambda f, w: V.PASS if w.override else V.OWNER_OR_ADMIN,   # Stations._may_release
}

# Who asks, as the lease has them: a session's role with --auth on (and the gateway's own sender),
# anyone with --auth off; StationGrants reads the role (rules.access), the table never does.
ASKERS = {
    'viewer': (True, 'viewer'), 'operator': (True, 'operator'), 'admin': (True, 'admin'),
    'open': (False, 'operator'), 'gateway': (True, 'gateway'), 'gateway, auth off': (False, 'gateway'),
}


class Sender:
    """What the lease is handed for a client: its attrs (a role, a person)."""

    def __init__(self, role: str):
        self.attrs = {'role': role, 'person': f'user {role}'}


def who_of(asker: str) -> Who:
    auth, role = ASKERS[asker]
    return StationGrants(auth=auth).who(Sender(role))


def all_facts():
    """Every state the lease can be in, as one asker sees it (a bar and an ended slot are facts of
    a station nobody owns)."""
    owners = [(FREE, b, e) for b in (False, True) for e in (False, True)] + [(MINE, False, False),
                                                                            (OTHERS, False, False)]
    for holder, (owner, barred, ended), halted, elsewhere, settling, moving, command in itertools.product(
            Holder, owners, (False, True), (False, True), (NONE, SELF, OTHER), (False, True), (False, True)):
        yield LeaseFacts(holder, owner, barred, ended, halted, elsewhere, settling, moving, command)


CASES = [(asker, command, facts) for asker in ASKERS for command in Command for facts in all_facts()]


def test_whom_the_roles_make():
    """The role is read in rules.access alone: who overrides, who is exempt, who is the gateway."""
    got = {asker: (w.override, w.exempt, w.gateway) for asker in ASKERS for w in [who_of(asker)]}
    assert got == {'viewer': (False, False, False), 'operator': (False, False, False),
                   'admin': (True, True, False), 'open': (True, False, False),
                   'gateway': (False, False, True), 'gateway, auth off': (True, False, True)}


def test_the_table_answers_as_the_lease_did():
    wrong = []
    for asker, command, facts in CASES:
        w = who_of(asker)
        got, want = verdict(w, command, facts), ORACLE[command](facts, w)
        if got is not want:
            wrong.append(f'{asker} {command} {facts}: {got}, the lease said {want}')
    assert not wrong, f'{len(wrong)} cases differ, e.g.:\n' + '\n'.join(wrong[:20])


def test_every_row_decides_a_case():
    """A row that decides no case could be changed unseen; each decides one at least (so a row
    changed changes an answer, and the test above sees it)."""
    deciding = {id(first_row(ROWS[command], who_of(asker), facts)) for asker, command, facts in CASES}
    dead = [r for r in TABLE if id(r) not in deciding]
    assert not dead, f'rows that decide nothing: {dead}'


def test_a_row_changed_is_seen():
    """The table test's own check: each row's answer swapped for another makes some case differ
    from the oracle."""
    for i, changed in enumerate(TABLE):
        other = V.PASS if changed.answer is not V.PASS else V.STOPPED
        rows = tuple(r if r is not changed else type(r)(r.command, r.when, other) for r in ROWS[changed.command])
        assert any(first_row(rows, who_of(a), f).answer is not ORACLE[c](f, who_of(a))
                   for a, c, f in CASES if c is changed.command), f'row {i} ({changed}) changed, nothing differs'


def test_what_the_lease_does_not_look_up():
    """The lease answers two cases before it looks the facts up, as the table would: a name that
    is no command passes (a command, a playback), and so does the holder's own command, whatever
    else holds (rules/lease.py: the holder's commands are most of them)."""
    for asker, command, facts in CASES:
        if (command in (Command.DRIVE, Command.PLAY) and not facts.command) or (
                command is Command.DRIVE and facts.holder is SELF):
            assert verdict(who_of(asker), command, facts) is V.PASS, (asker, command, facts)


# The rules as sentences (asker, command, facts, answer).
SENTENCES = [
    ('a student cannot take a station the teacher released from her',
     'operator', Command.TAKE, LeaseFacts(barred=True), V.RELEASED),
    ('a teacher takes a released station',
     'admin', Command.TAKE, LeaseFacts(barred=True), V.GRANT),
    ('a student drives a free station and takes its lease',
     'operator', Command.DRIVE, LeaseFacts(), V.GRANT),
    ('a zero passes a stop when nobody holds the lease',
     'operator', Command.DRIVE, LeaseFacts(halted=True, moving=False), V.PASS),
    ('nobody moves a stopped robot, not even the teacher, until someone takes it',
     'admin', Command.DRIVE, LeaseFacts(halted=True, owner=MINE), V.STOPPED),
    ('her other page drives her robot quietly',
     'operator', Command.DRIVE, LeaseFacts(holder=SAME, owner=MINE), V.QUIET),
    ('a student cannot take over another\'s lease; the teacher can',
     'operator', Command.TAKE, LeaseFacts(holder=OTHER), V.OTHER_DRIVES),
    ('the teacher takes over',
     'admin', Command.TAKE, LeaseFacts(holder=OTHER, owner=OTHERS), V.TAKE_OVER),
    ('with --auth off anyone takes over',
     'open', Command.TAKE, LeaseFacts(holder=OTHER), V.TAKE_OVER),
    ('with --auth off nobody passes a stop on another\'s station (only a signed-in admin does)',
     'open', Command.TAKE, LeaseFacts(halted=True, owner=OTHERS), V.STOPPED_OWNER_ONLY),
    ('only an admin stops', 'operator', Command.STOP, LeaseFacts(), V.ADMIN_STOPS),
    ('a page asking quietly never takes a stopped robot',
     'operator', Command.TAKE_IF_FREE, LeaseFacts(halted=True), V.NOTHING),
    ('a run cannot start into a stop; a teacher\'s can',
     'operator', Command.RUN, LeaseFacts(halted=True, owner=MINE), V.STOPPED_TAKE_FIRST),
    ('a teacher\'s run starts into a stop',
     'admin', Command.RUN, LeaseFacts(halted=True), V.PASS),
    ('a playback never takes a lease someone holds, even her own page\'s',
     'operator', Command.PLAY, LeaseFacts(holder=SAME, owner=MINE), V.DRIVING),
    ('a student cannot release another\'s station', 'operator', Command.RELEASE_STATION, LeaseFacts(),
     V.OWNER_OR_ADMIN),
    ('the gateway\'s own zeros pass a lease someone else holds',
     'gateway', Command.DRIVE, LeaseFacts(holder=OTHER, moving=False), V.PASS),
]


@pytest.mark.parametrize('sentence, asker, command, facts, answer', SENTENCES, ids=[s[0] for s in SENTENCES])
def test_the_rules_as_sentences(sentence, asker, command, facts, answer):
    assert verdict(who_of(asker), command, facts) is answer
