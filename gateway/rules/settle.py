"""The driver lease in a fleet of gateways (``store.fleet``): settled with PostgreSQL, and what the
other gateways did, done here.

A free lease is not this gateway's to give alone: another gateway may be giving it to someone else
at the same moment (two students publishing on one free station through two gateways within 10–40
ms both reached the robot when each gateway granted from memory). So the first command on a free
group *waits* for PostgreSQL's word (``FleetLease._settle``: one ``Fleet.take``, one transaction,
per lease). The publish door is not blocked: the rule answers ``Wait``, the door parks the message
with it, and every later message of that person on the group joins the same wait, in order. When
the word comes, each parked message asks the rules again (the lease now answers from memory: hers,
or someone else's, or a Stop that holds); when the database does not answer, they are refused
saying why. Nothing of the loser's reaches the robot.

While the gateway cannot confirm the shared state (``Fleet.confirmed``) it takes no new lease, and
the leases it holds end when their rows would lapse (``cut_off``): their drivers are stopped and
told why. The teacher's Stop and Release are rows (``stop`` state; the ended holds), so a gateway
that did not hear them applies them at its next read.
"""

from __future__ import annotations

import asyncio
import logging
import time

from ..store.fleet import Stopped, Unreachable

log = logging.getLogger('rosgate.lease')


class Wait:
    """A rule's answer that a message waits (a free lease being settled). ``then(fn)``: fn(None)
    once the rules may be asked again, fn(why) when it is refused."""

    __slots__ = ('waiting',)

    def __init__(self):
        self.waiting: list = []

    def then(self, fn) -> None:
        self.waiting.append(fn)

    def done(self, why: str | None = None) -> None:
        for fn in self.waiting:
            try:
                fn(why)
            except Exception:
                log.exception('a message waiting for the driver lease failed')
        self.waiting.clear()


class FleetLease:
    """The lease's part in a fleet (mixed into ``lease.Lease``; ``self.fleet`` None: alone)."""

    fleet = None

    def _settle(self, group: str, session, person: str, who: str) -> Wait:
        """PostgreSQL's word on session's taking the free lease of group; its messages wait."""
        waiting = self.settling.get(group)
        if waiting is None:
            waiting = self.settling[group] = (person, who, Wait())
            asyncio.ensure_future(self._settled(group, session, waiting))
        return waiting[2]

    async def _settled(self, group: str, session, waiting) -> None:
        person, who, wait = waiting
        why = None
        try:
            answer = await self.fleet.take('lease', group, person, who)
        except Unreachable as e:
            answer, why = None, f'{e}, so the driver lease for {group} cannot be confirmed with the other ' \
                                'gateways; try again in a moment'
        except Exception as e:   # a bug: said, and the messages refused
            log.exception('settling the driver lease for %s', group)
            answer, why = None, f'the driver lease for {group} could not be settled ({type(e).__name__})'
        finally:
            if self.settling.get(group) is waiting:
                del self.settling[group]
        if why is None and answer is None:
            if not session.closed and self.holders.get(group) is None and group not in self.halted:
                self._grant(group, session)
            elif self.holders.get(group) is None:
                self.fleet.drop('lease', group)     # nobody here to hold it any more
        elif isinstance(answer, Stopped):
            self.stopped_elsewhere(group, answer.by)
        elif answer is not None:
            log.info('driver lease for %s: PostgreSQL gave it to %s through another gateway, not to %s', group,
                     answer.who, who)
        wait.done(why)   # each message asks again: hers now, or refused naming the holder or the Stop

    def _halt(self, group: str, by: str) -> None:
        """A Stop in force: here, and a row every gateway honours (its leases of the group end)."""
        self.halted[group] = by
        if self.fleet is not None:
            self.fleet.put('stop', group, {'by': by}, ends=[('lease', group)],
                           why=f'{by} stopped the robot and freed the driver lease for {group}')

    def _unhalt(self, group: str, end: str | None = None) -> None:
        """The Stop ends; ``end``: who released the group (a Release), whose lease ends on any gateway."""
        was = self.halted.pop(group, None)
        if self.fleet is not None and (end or was is not None or ('stop', group) in self.fleet.values):
            self.fleet.remove('stop', group, ends=[('lease', group)] if end else (),
                              why=f'{end} released the driver lease for {group}' if end else None)

    def elsewhere(self, group: str, key: str | None) -> str | None:
        """Who drives group through another gateway of the fleet, if not person ``key``: a dict
        lookup (the fleet's mirror, kept current by its events and reads), never a round trip."""
        held = self.fleet.held('lease', group) if self.fleet is not None else None
        return held.who if held is not None and held.person != key else None

    def _drop_holder(self, group: str, why: str) -> None:
        holder = self.holders.get(group)
        if holder is not None:
            self._grant(group, None)
            if not holder.closed:
                holder.status('warning', f'{why}; your commands were stopped')

    # --- what the other gateways did (rules.fleet hands their events and rows in) -------------------

    def stopped_elsewhere(self, group: str, by: str) -> None:
        """The teacher's Stop through another gateway (its row, or its event): the same stop here."""
        self.stopped[group] = round(time.time(), 3)
        self.halted[group] = by
        self._drop_holder(group, f'{by} stopped the robot and freed the driver lease for {group}')
        self.stops.stop_group(group, self.group)
        self._announce()

    def released_elsewhere(self, group: str, by: str) -> None:
        """An admin's release (or the teacher's Release of the station) on another gateway."""
        self.halted.pop(group, None)
        self._drop_holder(group, f'{by} released the driver lease for {group}')
        self._announce()

    def unhalted_elsewhere(self, group: str) -> None:
        self.halted.pop(group, None)
        self._announce()

    def lapsed_elsewhere(self, group: str, hold) -> None:
        """The gateway that held the group's lease died (its row lapsed, nobody gave it back): what its
        driver left moving is zeroed from here, as that gateway's dead-man would have (one graph)."""
        log.info('driver lease for %s lapsed (%s through a gateway that stopped answering): stopping it',
                 group, hold.who)
        self.stops.zero_group(group, self.group)
        self._announce()

    def lost_elsewhere(self, group: str, hold, why: str | None = None) -> None:
        """Our lease of the group is gone from PostgreSQL: another gateway's client holds it (an
        admin took over, or both took it at once), or a Stop or Release there ended it (hold None)."""
        if hold is None:
            self._drop_holder(group, why or f'the driver lease for {group} was ended through another gateway')
        else:
            self._drop_holder(group, f'{hold.who} holds the driver lease for {group} through another gateway')

    def cut_off(self) -> None:
        """The shared state cannot be confirmed: our leases end as their rows lapse, drivers told why."""
        for group in list(self.holders):
            self._drop_holder(group, f'{self.fleet.why_unconfirmed()}, so it cannot keep the driver lease for '
                                     f'{group} (it ends with its expiry)')
        self._announce()
