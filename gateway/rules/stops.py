"""Stops: what moves in a group made still, the one way the lease and the slots do it.

``stop_session(party, group, group_of)``: one party's commands in the group zeroed (a driver who
lost the lease); ``stop_group(group, group_of)``: the teacher's Stop and a slot's end, every party's
commands in the group zeroed, then the hooks' ``on_group_stopped`` (playbacks into it end, runs in
it stop) — in that order, as before; ``zero_group(group, group_of)``: every velocity topic of the
group on the graph zeroed (what a dead gateway of a fleet left moving). ``group_of(topic)`` names a
topic's group: the caller's (the lease's groups), or by default the station whose namespace it is
in. Built before the lease and the slots, and given to them at construction.
"""

from __future__ import annotations

from collections.abc import Callable

from .ports import GroupEvents, Graph, Parties


class Stops:
    def __init__(self, *, safety, parties: Parties, graph: Graph, events: GroupEvents, stations):
        self.safety, self.parties, self.graph, self.events, self.stations = safety, parties, graph, events, stations

    def by_station(self, topic: str) -> str:
        """A topic's group without a lease: its station's namespace, or '/'."""
        return next((ns for ns in self.stations.stations() if topic.startswith(ns + '/')), '/')

    def stop_session(self, party, group: str, group_of: Callable[[str], str] | None = None) -> None:
        group_of = group_of or self.by_station
        self.safety.stop_session(party, lambda topic: group_of(topic) == group)

    def stop_group(self, group: str, group_of: Callable[[str], str] | None = None) -> None:
        group_of = group_of or self.by_station
        for party in self.parties.everyone():
            self.safety.stop_session(party, lambda topic: group_of(topic) == group)
        self.events.group_stopped(group, group_of)

    def zero_group(self, group: str, group_of: Callable[[str], str] | None = None) -> None:
        group_of = group_of or self.by_station
        self.safety.zero_topics([(t, ty) for t, ty in self.graph.topics() if group_of(t) == group])
