"""Recordings: topics over time, written as ROS 2 bags in MCAP storage, and played back (the HTTP
routes are ``web.recordings``').

A recording holds only topics its starter could subscribe to (``rules.access.may`` as that person:
the name globs, and the keepers, so another person's run output or live program is not recorded),
and a playback under a prefix publishes only where its starter could (refused up front with 403,
as is a playback into a station someone else drives, with 409). Recordings and playbacks belong to
who started them (with --auth): others, admins excepted, may not read, stop, play, download or
delete them (403), nor see them listed. An exercise attempt's recording is the teacher's evidence:
its student reads it and may not stop or delete it. One person runs at most ``max_per_person``
recordings at once and keeps at most ``person_bytes`` and ``person_count`` of them (429).

Each recording is a rosbag2 directory (metadata.yaml and ID.mcap) written by rosbags' writer:
CDR messages with their definitions, which ``ros2 bag``, Foxglove and the rosbags/mcap readers
open. The recorder is one more subscriber of each topic's shared fan-out, asking for cbor-raw
(the CDR bytes the backend makes once for every cbor-raw client), so it adds no backend
subscription; per message it reads those bytes back out of the cbor-raw frame and appends them
to the writer.
"""

from __future__ import annotations

import asyncio
import itertools
import logging
import re
import secrets
import shutil
import time
from dataclasses import dataclass
from fnmatch import fnmatchcase
from pathlib import Path

import cbor2

from ..rules.access import Action, Area, allowed, may
from ..rules.errors import Refusal
from ..rules.names import parse_globs
from .playback import Playback
from .ports import Graph, Names, Senders, Taps, Types
from ..settings import StorageSettings, data_dir
from ..rules.hooks import Hook

log = logging.getLogger('rosgate.recordings')
_ID = re.compile(r'rec-\d{8}-\d{6}-[0-9a-f]{4}')
_tap_ids = itertools.count(-1, -1)   # fan-out keys of recorders: negative, never a client's
RECORD_OVERHEAD = 31                 # bytes of an MCAP message record besides the data
POLL = 0.5                           # s between looks for new topics matching a recording's globs
OWNER_FILE = 'owner'                 # beside the bag: the name of who started it (absent: nobody's)
ATTEMPT_FILE = 'attempt'             # beside the bag of an exercise attempt's recording: the attempt's id


@dataclass(frozen=True)
class RecordingLimits:
    max_concurrent: int = 4
    max_per_person: int = 2           # so one person cannot hold every slot
    max_bytes: int = 256 * 2**20
    max_seconds: float = 3600.0
    default_seconds: float = 600.0
    disk_reserve: int = 256 * 2**20   # free space left on the disk, besides the cap
    person_bytes: int = 2 * 2**30     # what one person's kept recordings may take (admins and --record excepted)
    person_count: int = 500           # and how many


class _Tap:
    """Stands where a client session would in a topic's fan-out: its 'outbox' gets the cbor-raw
    frames ({'op': 'publish', 'topic', 'msg': {'secs', 'nsecs', 'bytes'}})."""

    closed = False

    def __init__(self, recording: Recording, topic: str):
        self.id = next(_tap_ids)
        self.recording, self.topic = recording, topic
        self.outbox = self

    def message(self, frame: bytes, binary: bool, key: object, queue_length: int) -> bool:
        try:
            self.recording.write(self.topic, cbor2.loads(frame)['msg']['bytes'])
        except Exception as e:   # never into the fan-out loop: the live clients come first
            log.exception('recording %s failed on %s', self.recording.id, self.topic)
            self.recording.manager.fail(self.recording, f'cannot write {self.topic}: {e}')
        return True

    def forget(self, key: object) -> None:
        pass


class Recording:
    def __init__(self, manager: RecordingManager, id: str, globs: tuple[str, ...], max_seconds: float | None,
                 owner: str | None = None, who=None, attempt: str | None = None):
        from rosbags.rosbag2 import StoragePlugin, Writer

        self.manager, self.id, self.globs, self.max_seconds = manager, id, globs, max_seconds
        self.owner, self.who, self.attempt = owner, who, attempt   # who: the Identity it records for
        self.counted = True   # against the limits (an exercise attempt's is not)
        self.path = manager.dir / id
        self.writer = Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
        self.writer.open()
        if owner is not None:
            (self.path / OWNER_FILE).write_text(owner)
        if attempt is not None:
            (self.path / ATTEMPT_FILE).write_text(attempt)
        self.state, self.reason = 'recording', None
        self.started, self.ended = time.time(), None
        self.messages, self.bytes = 0, 0
        self.connections: dict[str, object] = {}   # topic -> rosbags Connection
        self.taps: dict[str, tuple] = {}            # topic -> (fanout, _Tap)
        self.timer: asyncio.TimerHandle | None = None
        self.poller: asyncio.Task | None = None

    @property
    def file(self) -> Path:
        return self.path / f'{self.id}.mcap'

    def summary(self) -> dict:
        return {'id': self.id, 'state': self.state, 'reason': self.reason, 'topics': sorted(self.connections),
                'requested': list(self.globs), 'started': self.started, 'ended': self.ended,
                'messages': self.messages, 'bytes': self.bytes, 'max_seconds': self.max_seconds,
                'file': f'{self.id}.mcap', 'owner': self.owner, 'attempt': self.attempt}

    def wants(self, topic: str) -> bool:
        return any(fnmatchcase(topic, g) for g in self.globs)

    def add_topic(self, topic: str, type: str) -> None:
        types = self.manager.types
        msgdef = types.msg_def(type)
        text, rihs01 = definition(types, type, msgdef)
        types.to_cdr(type, {})   # a type the backend cannot serialize fails here, not in the fan-out
        self.connections[topic] = self.writer.add_connection(topic, type, msgdef=text, rihs01=rihs01)
        fan = self.manager.taps.fanout(topic, type)
        tap = _Tap(self, topic)
        self.taps[topic] = (fan, tap)
        sub = fan.add(tap, None, (0, 0, 'cbor-raw', None, None))
        fan.replay_latched(sub)

    def write(self, topic: str, data: bytes) -> None:
        if self.state != 'recording':
            return
        size = len(data) + RECORD_OVERHEAD
        if self.bytes + size > self.manager.limits.max_bytes:
            self.manager.stop(self, f'size cap of {self.manager.limits.max_bytes} bytes reached')
            return
        self.writer.write(self.connections[topic], time.time_ns(), data)
        self.messages += 1
        self.bytes += size

    def close(self, state: str, reason: str | None) -> None:
        for fan, tap in self.taps.values():
            fan.remove(tap, None)
        self.taps.clear()
        if self.timer is not None:
            self.timer.cancel()
        if self.poller is not None:
            self.poller.cancel()
        self.state, self.reason, self.ended = state, reason, time.time()
        self.writer.close()
        self.bytes = self.file.stat().st_size


def definition(backend: Types, type: str, msgdef) -> tuple[str, str]:
    """The definition text (with its dependencies, as ROS 2 stores it) and its RIHS01 hash."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    text = backend.full_text(msgdef)
    store = get_typestore(Stores.EMPTY)
    store.register(get_types_from_msg(text, type))
    return text, store.hash_rihs01(type)


class RecordingManager(Hook):
    """The recordings and playbacks: what each takes through the topics' fan-outs (``taps``, typed by
    ``types``, found in ``graph``), as whom (``names``: the rules' answer, and the lease), and the
    playbacks' publishing for their starters (``senders``)."""

    def __init__(self, dir: Path, limits: RecordingLimits = RecordingLimits(), *, taps: Taps, types: Types,
                 graph: Graph, senders: Senders, names: Names):
        self.dir, self.limits = Path(dir), limits
        self.taps, self.types, self.graph, self.senders, self.names = taps, types, graph, senders, names
        self.recordings: dict[str, Recording] = {}
        self.plays: dict[str, asyncio.Task] = {}
        self.playing: dict[str, Playback] = {}   # what each task of plays plays

    def active(self) -> list[Recording]:
        return [r for r in self.recordings.values() if r.state == 'recording']

    def start(self, globs: tuple[str, ...], max_seconds: float | None, owner: str | None = None,
              counted: bool = True, who=None, attempt: str | None = None) -> Recording:
        """owner: the name of who asks (None: auth is off, or the gateway's own --record); who: their
        Identity, as whom topics are taken. An exercise attempt's recording (its pose and commands:
        small, bounded by its time limit, its starts capped by ``rules.attempts``) is not ``counted``
        against the concurrent and per-person running limits: a class of 30 attempts at once."""
        lim = self.limits
        others = [r for r in self.active() if r.counted] if counted else []
        if len(others) >= lim.max_concurrent:
            raise Refusal(409, f'{lim.max_concurrent} recordings are already running; stop one first')
        if owner is not None and sum(r.owner == owner for r in others) >= lim.max_per_person:
            raise Refusal(429, f'{owner} already runs {lim.max_per_person} recordings; stop one first')
        if owner is not None and not allowed(who, Action.EXEMPT, Area.RECORDINGS):
            kept = [r for r in self.listing() if r.get('owner') == owner]
            size = sum(r.get('bytes') or 0 for r in kept)
            if len(kept) >= lim.person_count or size >= lim.person_bytes:
                raise Refusal(429, f'{owner} keeps {len(kept)} recordings of {size} bytes, the most one '
                              f'person may ({lim.person_count}, {lim.person_bytes} bytes): delete '
                              'some, or ask the teacher')
        self.dir.mkdir(parents=True, exist_ok=True)
        free = shutil.disk_usage(self.dir).free
        if free < lim.max_bytes + lim.disk_reserve:
            log.warning('recordings: only %d MiB free in %s', free // 2**20, self.dir)   # the folder: the admins'
            raise Refusal(507, f'only {free // 2**20} MiB free for recordings; a recording needs '
                          f'{(lim.max_bytes + lim.disk_reserve) // 2**20} MiB')
        rec_id = f"rec-{time.strftime('%Y%m%d-%H%M%S')}-{secrets.token_hex(2)}"
        try:
            rec = Recording(self, rec_id, globs, max_seconds, owner, who, attempt)
            rec.counted = counted
        except Exception:   # rosbags' WriterError, OSError: the log says where (a path is the admins')
            log.exception('cannot create recording %s in %s', rec_id, self.dir)
            raise Refusal(500, 'cannot create the recording (the gateway\'s log says why)') from None
        self.recordings[rec_id] = rec
        try:
            self._match(rec)
        except Exception:
            self.stop(rec, 'could not subscribe')
            raise
        loop = asyncio.get_running_loop()
        if max_seconds:
            rec.timer = loop.call_later(max_seconds, self.stop, rec, f'max_seconds of {max_seconds:g} s reached')
        rec.poller = asyncio.ensure_future(self._poll(rec))
        log.info('recording %s started by %r: %r', rec_id, owner, globs)
        return rec

    def _match(self, rec: Recording) -> None:
        """Take the topics the globs of the recording ask for and its starter may subscribe to (a
        recording is a way to subscribe: ``may`` as them)."""
        for topic, type in self.graph.topics():
            if (topic not in rec.connections and rec.wants(topic)
                    and may(self.names, rec.who, 'subscribe', topic) is None):
                try:
                    rec.add_topic(topic, type)
                except Exception as e:   # an unknown type, a definition rosbags cannot parse, ...
                    log.warning('recording %s: cannot record %r (%s): %s', rec.id, topic, type, e)
                    rec.connections.setdefault(topic, None)

    async def _poll(self, rec: Recording) -> None:
        while rec.state == 'recording':
            await asyncio.sleep(POLL)
            if rec.state == 'recording':
                self._match(rec)

    def stop(self, rec: Recording, reason: str | None = None) -> None:
        if rec.state != 'recording':
            return
        try:
            rec.close('done', reason)
        except Exception as e:   # a full disk, ...: say so, keep serving
            log.exception('recording %s could not be closed', rec.id)
            rec.state, rec.reason, rec.ended = 'failed', f'could not finish the file: {e}', time.time()
        log.info('recording %s %s: %d messages, %d bytes%s', rec.id, rec.state, rec.messages, rec.bytes,
                 f' ({reason})' if reason else '')

    def fail(self, rec: Recording, reason: str) -> None:
        """Stop taking messages; the file is finished with what it has."""
        self.stop(rec, reason)
        if rec.state == 'done':
            rec.state = 'failed'

    def listing(self, identity=None, everyone: bool = True) -> list[dict]:
        """The recordings (this run's and those on disk): everyone's, or (``everyone`` False) those of
        ``identity`` alone."""
        out = {r.id: r.summary() for r in self.recordings.values()}
        if self.dir.is_dir():
            for path in sorted(self.dir.iterdir()):
                mcap = path / f'{path.name}.mcap'
                if path.name not in out and _ID.fullmatch(path.name) and mcap.is_file():
                    st = mcap.stat()
                    out[path.name] = {'id': path.name, 'state': 'done', 'bytes': st.st_size, 'ended': st.st_mtime,
                                      'file': mcap.name, 'owner': self.owner(path.name),
                                      'attempt': self.attempt_of(path.name)}
        if not everyone:
            mine = identity.owner if identity is not None else None
            out = {k: v for k, v in out.items() if mine is not None and v.get('owner') == mine}
        for rec_id, summary in out.items():
            summary['playing'] = self.is_playing(rec_id)
        return sorted(out.values(), key=lambda r: r['id'])

    def attempt_of(self, rec_id: str) -> str | None:
        """The exercise attempt a recording is the record of (None: none)."""
        rec = self.recordings.get(rec_id)
        if rec is not None:
            return rec.attempt
        try:
            return (self.dir / rec_id / ATTEMPT_FILE).read_text() or None
        except (OSError, UnicodeDecodeError):
            return None

    def owner(self, rec_id: str) -> str | None:
        """Who started a recording (None: nobody signed in, or the gateway's --record)."""
        rec = self.recordings.get(rec_id)
        if rec is not None:
            return rec.owner
        try:
            return (self.dir / rec_id / OWNER_FILE).read_text() or None
        except (OSError, UnicodeDecodeError):
            return None

    def check_owner(self, rec_id: str, identity, verb: str, changes: bool = False) -> None:
        """Only who started a recording (or an admin) may read, stop, play, download or delete it;
        one that nobody signed in started is an admin's to change when auth is on. An attempt's
        recording (``changes``: to stop or delete it) is an admin's alone: the teacher's evidence."""
        if allowed(identity, Action.MANAGE, Area.RECORDINGS) or not _ID.fullmatch(rec_id):
            return   # a name that is no recording's gets its 404 from path()
        if rec_id not in self.recordings and not (self.dir / rec_id).is_dir():
            return
        owner = self.owner(rec_id)
        if owner != identity.owner:
            whose = f"{owner}'s" if owner else 'not yours'
            raise Refusal(403, f'recording {rec_id} is {whose}; {identity.name} may not {verb} it')
        attempt = self.attempt_of(rec_id) if changes else None
        if attempt is not None:
            raise Refusal(403, f'recording {rec_id} is the record of exercise attempt {attempt}, the '
                          f'teacher\'s evidence: {identity.name} may read it, not {verb} it')

    def path(self, rec_id: str) -> Path:
        if not _ID.fullmatch(rec_id):
            raise Refusal(404, f'no recording {rec_id[:80]!r}')
        rec = self.recordings.get(rec_id)
        if rec is not None and rec.state == 'recording':
            raise Refusal(409, f'recording {rec_id} is still running; stop it first')
        path = self.dir / rec_id
        if not (path / f'{rec_id}.mcap').is_file():
            raise Refusal(404, f'no recording {rec_id!r}')
        return path

    def delete(self, rec_id: str) -> None:
        """A finished recording gone from the disk (its playback stopped first)."""
        path = self.path(rec_id)
        self.stop_playing(rec_id)
        shutil.rmtree(path)
        self.recordings.pop(rec_id, None)

    # --- playback -----------------------------------------------------------------------------

    def play(self, rec_id: str, rate: float, prefix: str, identity=None, person: str | None = None) -> dict:
        """Start playing (as ``identity``): refused up front (403) where the name globs would
        refuse that person's publishing, and (409) into a robot someone else drives."""
        if rec_id in self.plays and not self.plays[rec_id].done():
            raise Refusal(409, f'recording {rec_id} is already playing')
        path = self.path(rec_id)
        name, role = (identity.owner, identity.role) if identity is not None else ('playback', None)
        try:
            playback = Playback(self.senders, path, rate, prefix, name, role, person)
        except Exception as e:   # a damaged file, a type rosbags cannot parse
            raise Refusal(422, f'cannot play {rec_id}: {e}') from None
        try:
            self._may_play(playback, name, role, person)
        except BaseException:
            playback.reader.close()
            raise
        task = self.plays[rec_id] = asyncio.ensure_future(playback.run())
        self.playing[rec_id] = playback
        task.add_done_callback(lambda t: t.cancelled() or t.exception() is None or log.error(
            'playing %s failed: %s', rec_id, t.exception()))
        return playback.summary()

    def _may_play(self, playback: Playback, name: str, role: str | None, person: str | None) -> None:
        probe = self.senders.probe(name, role, person)   # a sender never opened
        lease = self.names.lease
        for topic, type in playback.targets():
            why = may(self.names, probe, 'publish', topic)
            if why is not None:
                raise Refusal(403, f'cannot play into {topic}: {why}')
            refusal = None if lease is None else lease.topic_refusal(person, topic, type) if lease.is_command(
                topic, type) else lease.names.refusal(probe, topic)   # a station's other topics: its holder's
            if refusal is not None:
                raise Refusal(409, f'cannot play into {topic}: {refusal}')

    def stop_playing(self, rec_id: str) -> bool:
        task = self.plays.pop(rec_id, None)
        self.playing.pop(rec_id, None)
        if task is None or task.done():
            return False
        task.cancel()
        return True

    def is_playing(self, rec_id: str) -> bool:
        task = self.plays.get(rec_id)
        return task is not None and not task.done()

    def player(self, rec_id: str) -> str | None:
        """The name of who started the playback of a recording going on now (None: none, or nobody's)."""
        playback = self.playing.get(rec_id)
        return playback.who[0] if playback is not None and self.is_playing(rec_id) else None

    # --- gateway hooks ------------------------------------------------------------------------

    def on_group_stopped(self, group: str, group_of) -> None:
        """An admin stopped a robot ("stop NS" on /rosgate/control): the playbacks into it end."""
        for rec_id, playback in list(self.playing.items()):
            if any(group_of(topic) == group for topic, _ in playback.targets()):
                playback.refused = f'{group} was stopped'
                if self.stop_playing(rec_id):
                    log.info('playing %s ended: %s was stopped', rec_id, group)

    async def on_shutdown(self) -> None:
        for rec in self.active():
            self.stop(rec, 'the gateway shut down')
        for task in self.plays.values():
            task.cancel()


def start_recordings(storage: StorageSettings, *, taps: Taps, types: Types, graph: Graph,
                     senders: Senders, names: Names) -> RecordingManager:
    """The recordings' manager (a part of the gateway's ``hooks``); with --record, the start-up
    recording begins once the loop runs."""
    record = storage.record
    folder = storage.recordings_dir or record
    manager = RecordingManager(Path(folder) if folder else default_recordings_dir(), taps=taps, types=types,
                               graph=graph, senders=senders, names=names)
    if record:
        globs = parse_globs(storage.record_topics) or ('/*',)
        asyncio.get_running_loop().call_soon(_start_up, manager, globs)
    return manager


def _start_up(manager: RecordingManager, globs: tuple[str, ...]) -> None:
    try:
        rec = manager.start(globs, None)
    except Refusal as e:
        log.error('--record: %s', e.message)
        return
    log.info('--record: recording %s into %s', ', '.join(globs), rec.path)


def default_recordings_dir() -> Path:
    return data_dir('recordings')
