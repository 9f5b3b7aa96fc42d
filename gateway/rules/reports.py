"""Program reports: what an IDE tells the teacher's view about its program, stamped by the gateway.

An IDE publishes std_msgs/String on ``NS/rosgate/program``, latched, carrying JSON {user, name,
state, error, program, line, at} (``ide/js/ide/report.js``); the class view (``/class``) shows it on the
station's tile. Tried as a class would: a student published a report on another's station with
``"user": "ada"`` and the teacher's view showed it as hers; and anyone signed in, a viewer too,
subscribed to every station's report and read every student's program as it was being written.

- At the publish door (``publish_hook``) the gateway stamps every report: ``user`` becomes the
  sender's signed-in name (its connection's label with auth off) and ``by`` says who sent it from
  which connection: {"name", "role", "client", "remote"}. A report that is not a JSON object is
  refused, and so is one on a station another person owns (it is hers to report on).
- A report is read (``keeper``: subscribe, a keeper of ``rules.access``) by the admins and by the
  person whose station it is (everyone with auth off, as every request is an admin's then); a
  report topic of no station, by the admins alone.
"""

from __future__ import annotations

import json

from protocol.errors import ProtocolError

from .access import Action, Area, allowed, person_of, role_of
from .stations import person

TAIL = '/rosgate/program'


def is_report(topic: str) -> bool:
    return topic.endswith(TAIL)


def station_of(topic: str) -> str:
    """'/s01/rosgate/program' -> '/s01'."""
    return topic[:-len(TAIL)] or '/'


class Reports:
    def __init__(self, stations, *, auth: bool):
        self.stations, self.auth = stations, auth

    def _owner(self, topic: str):
        ns = station_of(topic)
        return self.stations.owner(ns) if ns in self.stations.stations() else None

    def publish_hook(self, sender, pub, msg, issued=None):
        if not is_report(pub.topic):
            return msg
        try:
            report = json.loads(msg.get('data', ''))
        except (TypeError, ValueError):
            report = None
        if not isinstance(report, dict):
            raise ProtocolError(f'{pub.topic}: a program report is a JSON object ({{"name", "state", ...}})')
        owner = self._owner(pub.topic)
        if owner is not None and owner.person != person(sender) and not allowed(sender if self.auth else None, Action.MANAGE, Area.REPORTS):
            raise ProtocolError(f'{pub.topic}: {station_of(pub.topic)} is {owner.name}\'s station: its program '
                                'report is theirs')
        attrs = sender.attrs
        name = attrs.get('name') or f'client {sender.id}'
        report['user'] = name
        report['by'] = {'name': name, 'role': role_of(sender), 'client': sender.id,
                        'remote': getattr(sender, 'remote', '')}
        return {**msg, 'data': json.dumps(report)}

    def keeper(self, who, action: str, name: str) -> str | None:
        """Who may read a report: the admins and its station's person."""
        if action != 'subscribe' or not is_report(name) or not self.auth or allowed(who, Action.MANAGE, Area.REPORTS):
            return None
        owner = self._owner(name)
        if owner is not None and owner.person == person_of(who):
            return None
        whose = f"{owner.name}'s" if owner is not None else 'another person\'s'
        return f'{name}: {whose} program as it is written is for them and the teacher (admins)'
