"""The driver lease's commands as one table: who (its standing on the stations) × command × lease
state -> an answer.

The Lease (``rules.lease``) computes the facts of a group for the one asking (``LeaseFacts``: who
holds it, whose station it is, a bar, an ended slot, a Stop, a driver elsewhere, a lease being
settled, whether the command moves and is a command at all), asks ``StationGrants.verdict``
(``rules.access``: the role decides there, and only there, whether the asker *overrides* others'
leases and claims -- an admin, or anyone with --auth off -- and whether she is *exempt* from a
teacher's Stop, bar or ended slot -- a signed-in admin), and does what the answer says. An answer
is a refusal (its reason; the lease words it, naming who holds what) or an allow with its effect,
which is state, not permission (grant the lease, quietly between one person's clients, lend it to a
run, halt, free ...). ``TABLE`` is read top to bottom per command; the first row whose conditions
all hold answers. tests/rules/test_lease_table.py checks every case against a transcription of
the lease's branches as they were, and that every row decides some case.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from functools import lru_cache
from typing import NamedTuple


class Command(StrEnum):
    TAKE = 'take'                       # "take [NS]" on /rosgate/control (and a run's take)
    TAKE_IF_FREE = 'take-if-free'       # what a page sends by itself
    RELEASE = 'release'                 # "release NS"
    STOP = 'stop'                       # "stop NS"
    DRIVE = 'drive'                     # a command (velocity topic, --control-glob topic, call or goal)
    RUN = 'run'                         # a robot-side run starting on a station
    PLAY = 'play'                       # a playback into a command topic
    RELEASE_STATION = 'release-station'  # the claims: another's station, or all of them


class Holder(StrEnum):
    NONE = 'nobody'
    SELF = 'this client'
    SAME_PERSON = 'another client of the same person'
    OTHER = 'someone else'


class Owning(StrEnum):
    FREE = 'nobody\'s station'
    MINE = 'the asker\'s station'
    OTHERS = 'another\'s station'


class LeaseFacts(NamedTuple):
    """A group's lease as the one asking sees it (``Lease.facts``): pure data (a tuple: made and
    hashed for every command that is not its holder's)."""
    holder: Holder = Holder.NONE
    owner: Owning = Owning.FREE
    barred: bool = False       # the teacher released it from this person (owner FREE only)
    ended: bool = False        # another's booked slot is on, or hers just ended (owner FREE only)
    halted: bool = False       # a Stop holds
    elsewhere: bool = False    # someone else drives it through another gateway of the fleet
    settling: Holder = Holder.NONE   # NONE, SELF (her free lease is being asked of PostgreSQL) or OTHER
    moving: bool = True        # the command moves (a zero stops)
    command: bool = True       # the name is a command name (velocity type or --control-glob)

    @property
    def mine(self) -> bool:
        """The station is the asker's to drive: nobody's and not barred from her, or hers."""
        return (self.owner is Owning.FREE and not self.barred) or self.owner is Owning.MINE


class Who(NamedTuple):
    """The asker as the table reads it (``StationGrants.who``)."""
    override: bool = False     # takes over others' leases, releases others' stations, stops
    exempt: bool = False       # passes a Stop, a bar, an ended slot (a signed-in admin)
    gateway: bool = False      # the gateway itself (its zeros pass)


class Verdict(StrEnum):
    # allowed, and the effect the lease performs
    PASS = 'pass'                  # nothing to do
    GRANT = 'grant'                # grant the free lease (in a fleet once PostgreSQL agrees)
    QUIET = 'quiet'                # grant it from another client of the same person, without a word
    WAIT = 'wait'                  # her own free lease is being settled: wait with it
    KEEP = 'keep'                  # she holds it already: a Stop of hers ends
    SHARE = 'share'                # from her other client (lent back when a run ends)
    TAKE_OVER = 'take over'        # from someone else (they stop and are told by whom)
    HALT = 'halt'                  # a Stop: free the holder, stop the group
    FREE = 'free'                  # give it back
    FREE_BY = 'free by'            # free another's, and end a Stop
    NOTHING = 'nothing'            # asked quietly, not given (take-if-free)
    # refused, for this reason (the lease words it)
    ENDED = 'ended'
    RELEASED = 'released'
    STOPPED = 'stopped'
    STOPPED_OWNER_ONLY = 'stopped: its owner only'
    STOPPED_TAKE_FIRST = 'stopped: take it first'
    OTHERS_STATION = 'another\'s station'
    ELSEWHERE = 'driven elsewhere'
    OTHER_DRIVES = 'someone else drives'
    BEING_TAKEN = 'being taken'
    HOLDS_LEASE = 'someone else holds the lease'
    DRIVING = 'someone drives'
    ADMIN_STOPS = 'only an admin stops'
    ADMIN_RELEASES = 'only an admin releases'
    OWNER_OR_ADMIN = 'only its owner or an admin'

    @property
    def refused(self) -> bool:
        return self in REFUSALS


REFUSALS = frozenset({Verdict.ENDED, Verdict.RELEASED, Verdict.STOPPED, Verdict.STOPPED_OWNER_ONLY,
                      Verdict.STOPPED_TAKE_FIRST, Verdict.OTHERS_STATION, Verdict.ELSEWHERE, Verdict.OTHER_DRIVES,
                      Verdict.BEING_TAKEN, Verdict.HOLDS_LEASE, Verdict.DRIVING, Verdict.ADMIN_STOPS,
                      Verdict.ADMIN_RELEASES, Verdict.OWNER_OR_ADMIN})

NONE, SELF, SAME, OTHER = Holder.NONE, Holder.SELF, Holder.SAME_PERSON, Holder.OTHER
FREE, MINE, OTHERS = Owning.FREE, Owning.MINE, Owning.OTHERS
T, F = True, False


@dataclass(frozen=True, slots=True)
class Row:
    """Conditions (a fact or a trait of the asker: the value it must have, or a set of them) and
    the answer when all hold."""
    command: Command
    when: tuple[tuple[str, object], ...]
    answer: Verdict

    def holds(self, facts: LeaseFacts, who: Who) -> bool:
        for key, want in self.when:
            have = getattr(who, key) if key in WHO_KEYS else getattr(facts, key)
            if not (have in want if isinstance(want, frozenset) else have == want):
                return False
        return True


WHO_KEYS = frozenset({'override', 'exempt', 'gateway'})


def row(asked: Command, answer: Verdict, **when) -> Row:
    return Row(asked, tuple((k, frozenset(v) if isinstance(v, (set, tuple)) else v) for k, v in when.items()),
               answer)


C, V = Command, Verdict
TABLE: tuple[Row, ...] = (
    row(C.TAKE, V.ENDED, ended=T, override=F),
    row(C.TAKE, V.RELEASED, barred=T, override=F),
    row(C.TAKE, V.STOPPED_OWNER_ONLY, halted=T, mine=F, exempt=F),
    row(C.TAKE, V.OTHERS_STATION, mine=F, override=F),
    row(C.TAKE, V.ELSEWHERE, holder=NONE, elsewhere=T, override=F),
    row(C.TAKE, V.KEEP, holder=SELF),
    row(C.TAKE, V.TAKE_OVER, holder=NONE, elsewhere=T),
    row(C.TAKE, V.GRANT, holder=NONE),
    row(C.TAKE, V.SHARE, holder=SAME),
    row(C.TAKE, V.TAKE_OVER, override=T),
    row(C.TAKE, V.OTHER_DRIVES),

    row(C.TAKE_IF_FREE, V.NOTHING, ended=T, override=F),
    row(C.TAKE_IF_FREE, V.GRANT, holder=NONE, mine=T, halted=F, elsewhere=F),
    row(C.TAKE_IF_FREE, V.NOTHING),

    row(C.STOP, V.ADMIN_STOPS, override=F),
    row(C.STOP, V.HALT),

    row(C.RELEASE, V.FREE, holder=SELF),
    row(C.RELEASE, V.FREE_BY, override=T),
    row(C.RELEASE, V.ADMIN_RELEASES, holder=(SAME, OTHER)),
    row(C.RELEASE, V.PASS),

    row(C.DRIVE, V.PASS, command=F),
    row(C.DRIVE, V.PASS, gateway=T, moving=F),
    row(C.DRIVE, V.PASS, holder=SELF),
    row(C.DRIVE, V.PASS, halted=T, holder=NONE, moving=F),
    row(C.DRIVE, V.STOPPED, halted=T),
    row(C.DRIVE, V.WAIT, settling=SELF),
    row(C.DRIVE, V.PASS, settling=OTHER, moving=F),
    row(C.DRIVE, V.BEING_TAKEN, settling=OTHER),
    row(C.DRIVE, V.QUIET, holder=SAME, moving=T),
    row(C.DRIVE, V.PASS, holder=SAME),
    row(C.DRIVE, V.ELSEWHERE, holder=NONE, elsewhere=T),
    row(C.DRIVE, V.GRANT, holder=NONE, owner=FREE, barred=F, ended=F),
    row(C.DRIVE, V.GRANT, holder=NONE, owner=MINE),
    row(C.DRIVE, V.PASS, holder=NONE, moving=F),
    row(C.DRIVE, V.RELEASED, holder=NONE, barred=T),
    row(C.DRIVE, V.ENDED, holder=NONE, ended=T),
    row(C.DRIVE, V.OTHERS_STATION, holder=NONE),
    row(C.DRIVE, V.OTHER_DRIVES),

    row(C.RUN, V.STOPPED_TAKE_FIRST, halted=T, exempt=F),
    row(C.RUN, V.RELEASED, owner=FREE, barred=T, exempt=F),
    row(C.RUN, V.OTHERS_STATION, owner=OTHERS, override=F),
    row(C.RUN, V.ENDED, owner=FREE, ended=T, exempt=F),
    row(C.RUN, V.HOLDS_LEASE, holder=OTHER, override=F),
    row(C.RUN, V.PASS),

    row(C.PLAY, V.PASS, command=F),
    row(C.PLAY, V.STOPPED, halted=T),
    row(C.PLAY, V.DRIVING, holder=(SELF, SAME, OTHER)),
    row(C.PLAY, V.RELEASED, owner=FREE, barred=T),
    row(C.PLAY, V.OTHERS_STATION, owner=OTHERS),
    row(C.PLAY, V.ENDED, owner=FREE, ended=T),
    row(C.PLAY, V.PASS),

    row(C.RELEASE_STATION, V.PASS, override=T),
    row(C.RELEASE_STATION, V.OWNER_OR_ADMIN),
)
ROWS: dict[Command, tuple[Row, ...]] = {c: tuple(r for r in TABLE if r.command is c) for c in Command}


def first_row(rows: tuple[Row, ...], who: Who, facts: LeaseFacts) -> Row:
    """The first of ``rows`` whose conditions hold (every command's last row holds always)."""
    for r in rows:
        if r.holds(facts, who):
            return r
    raise LookupError(f'no row of the lease table answers {who} in {facts}')


@lru_cache(maxsize=8192)
def verdict(who: Who, command: Command, facts: LeaseFacts) -> Verdict:
    """What ``TABLE`` answers (the cases are few: remembered)."""
    return first_row(ROWS[command], who, facts).answer
