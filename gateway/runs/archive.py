"""Every run kept in the store: its source, kind, starter, station, start, end, exit code, the
whole output up to a cap per run, and where its recording is.

Two tables: ``runs`` (one row a run, written when it starts and again when it ends) and
``run_output`` (its output in chunks, in order). Lines wait in memory and go to the store's thread
as one batch every ``FLUSH`` s (``Store.submit``): one insert a run a batch, not one a line.
30 runs printing at 1 kHz (30,000 lines a second) cost the archive about 2 % of a core with
SQLite (``make bench ARGS=runs``). Past the cap (``--run-output-cap``, 1 MiB) nothing more is
kept but a line saying where the output was cut; the row keeps how much came in all.

Retention (``--runs-keep-days``, ``--runs-keep-count`` a person, ``--runs-keep-bytes`` in all,
``--runs-keep-share`` of it a person) deletes the oldest ended runs, their output and their
recording, at the gateway's start, at each run's start and hourly (a run its gateway never ended,
having died, is ``interrupted`` then). One budget for everyone let one person's runs evict every
other person's: now a person's runs past their share go first (their own oldest), and past the
whole budget the oldest of whoever keeps the most. A run is refused (507) when it could not fit:
the runs going now, each counted at its cap, would pass ``--runs-keep-bytes`` (or, theirs, the
starter's share: 429), or the disk has less than a run's cap and ``DISK_RESERVE`` free. Only this
module writes these tables.

May import: ``store``, ``rules`` (a part of ``runs``).
"""

from __future__ import annotations

import asyncio
import logging
import shutil
import time
from pathlib import Path

import sqlalchemy as sa

from ..rules.errors import Refusal
from ..store import METADATA

log = logging.getLogger('rosgate.runs')
FLUSH = 0.5                   # s between batches of output to the store
DISK_RESERVE = 256 * 2**20    # free space left on the store's disk besides a run's cap
PRUNE_EVERY = 3600.0          # s between retention passes besides those at a run's start
LOST_AFTER = 2 * 3600.0       # s: a run not ended this long after its start ended with a gateway that died
NOTE_ROOM = 128               # bytes of the cap left for the line that says where the output was cut

RUNS = sa.Table(
    'runs', METADATA,
    sa.Column('id', sa.String(16), primary_key=True),
    sa.Column('name', sa.String(64), nullable=False),
    sa.Column('kind', sa.String(32), nullable=False),
    sa.Column('owner', sa.String(255)),            # the starter's key (None: auth off)
    sa.Column('who', sa.String(255)),              # the starter's name, as pages show it
    sa.Column('ns', sa.String(255), nullable=False),
    sa.Column('started', sa.Float, nullable=False),
    sa.Column('ended', sa.Float),
    sa.Column('state', sa.String(16), nullable=False),
    sa.Column('exit_code', sa.Integer),
    sa.Column('reason', sa.Text),
    sa.Column('source', sa.Text, nullable=False),
    sa.Column('output_bytes', sa.BigInteger, nullable=False, default=0),   # kept
    sa.Column('output_seen', sa.BigInteger, nullable=False, default=0),    # came in all
    sa.Column('cut', sa.Boolean, nullable=False, default=False),
    sa.Column('recording', sa.Text),               # the MCAP file's path (None: not recorded)
    sa.Column('recording_bytes', sa.BigInteger, nullable=False, default=0),
    sa.Index('runs_owner_started', 'owner', 'started'))
OUTPUT = sa.Table(
    'run_output', METADATA,
    sa.Column('run', sa.String(16), nullable=False),
    sa.Column('seq', sa.Integer, nullable=False),
    sa.Column('text', sa.Text, nullable=False),
    sa.PrimaryKeyConstraint('run', 'seq', name='run_output_pk'))


class ArchiveFull(Refusal):
    """No room for one more run: ``status`` 507."""


class Kept:
    """What the archive holds of one run going now (the rest is its ``Run``)."""

    def __init__(self):
        self.pending: list[str] = []
        self.seq = 0
        self.kept = self.seen = 0
        self.cut = False


class Archive:
    def __init__(self, store, *, cap: int, keep_days: float, keep_count: int, keep_bytes: int,
                 keep_share: float = 1.0):
        self.store, self.cap = store, cap
        self.keep_days, self.keep_count, self.keep_bytes = keep_days, keep_count, keep_bytes
        self.share = int(keep_bytes * keep_share)   # the most one person's kept runs take
        self.owners: dict[str, str | None] = {}     # run going -> its starter's key
        self.going: dict[str, Kept] = {}
        self.timer: asyncio.TimerHandle | None = None
        self.pruner: asyncio.TimerHandle | None = None
        store.run_now(self.prune)

    # --- a run --------------------------------------------------------------------------------

    def room(self, record_bytes: int = 0, owner: str | None = None) -> None:
        """Refuse (ArchiveFull, 507) a run the archive or the disk could not hold, and (429) one past
        its starter's share (``owner``: their key; None, with auth off, has the whole archive)."""
        need = self.cap + record_bytes
        reserved = len(self.going) * self.cap
        if reserved + need > self.keep_bytes:
            raise ArchiveFull(507, f'the run archive holds at most {self.keep_bytes} bytes (--runs-keep-bytes) and '
                                   f'{len(self.going)} runs going may take {reserved} of them (--run-output-cap '
                                   f'{self.cap}); wait for one to end')
        theirs = sum(1 for o in self.owners.values() if owner is not None and o == owner) * self.cap
        if owner is not None and theirs + need > self.share:
            raise ArchiveFull(429, f'{owner}\'s runs going may take {theirs} bytes of their share of the run '
                                   f'archive, {self.share} bytes (--runs-keep-share); wait for one to end')
        where = self.store.path.parent if self.store.path is not None else None
        if where is not None:
            free = shutil.disk_usage(where).free
            if free < need + DISK_RESERVE:
                raise ArchiveFull(507, f'only {free // 2**20} MiB free on the store\'s disk; a kept run needs '
                                       f'{(need + DISK_RESERVE) // 2**20} MiB')

    def begin(self, run, source: str, kind: str) -> None:
        self.going[run.id] = Kept()
        self.owners[run.id] = run.owner
        row = dict(id=run.id, name=run.name, kind=kind, owner=run.owner, who=run.who, ns=run.ns,
                   started=run.started, state=run.state, source=source)
        budget = self.keep_bytes - len(self.going) * self.cap
        reserved = {}
        for owner in self.owners.values():
            reserved[owner] = reserved.get(owner, 0) + self.cap
        self.store.submit(lambda c: (c.execute(RUNS.insert().values(**row)),
                                     self.prune(c, budget=budget, reserved=reserved)))
        self._schedule_prune()

    def line(self, run_id: str, line: str) -> None:
        k = self.going.get(run_id)
        if k is None:
            return
        size = len(line.encode())
        k.seen += size
        if k.cut:
            return
        if k.kept + size > self.cap - NOTE_ROOM:
            k.cut = True
            line = (f'[output cut here after {k.kept} bytes (--run-output-cap {self.cap}): '
                    'the rest is not kept]\n')
            size = len(line.encode())
        k.kept += size
        k.pending.append(line)
        if self.timer is None:
            self.timer = asyncio.get_running_loop().call_later(FLUSH, self.flush)

    def flush(self) -> None:
        self.timer = None
        batch = []
        for run_id, k in self.going.items():
            if k.pending:
                batch.append({'run': run_id, 'seq': k.seq, 'text': ''.join(k.pending)})
                k.seq += 1
                k.pending.clear()
        if batch:
            self.store.submit(lambda c: c.execute(OUTPUT.insert(), batch))

    def end(self, run, recording: tuple[str, int] | None) -> None:
        """The run ended: its last output, its state, and its recording (path, bytes) if it had one."""
        k = self.going.get(run.id)
        if k is None:
            return
        self.flush()
        del self.going[run.id]
        self.owners.pop(run.id, None)
        values = dict(ended=run.ended, state=run.state, exit_code=run.exit_code, reason=run.reason,
                      output_bytes=k.kept, output_seen=k.seen, cut=k.cut)
        if recording is not None:
            values.update(recording=recording[0], recording_bytes=recording[1])
        self.store.submit(lambda c: c.execute(RUNS.update().where(RUNS.c.id == run.id).values(**values)))

    def pending(self, run_id: str) -> str:
        """Output of a run going now that is not in the store yet."""
        k = self.going.get(run_id)
        return ''.join(k.pending) if k is not None else ''

    # --- reading (on the store's thread) ------------------------------------------------------

    @staticmethod
    def rows(conn: sa.Connection, owner: str | None, everyone: bool, limit: int = 1000) -> list[dict]:
        cols = [c for c in RUNS.c if c.name != 'source']
        q = sa.select(*cols).order_by(RUNS.c.started.desc()).limit(limit)
        if not everyone:
            q = q.where(RUNS.c.owner == owner)
        return [dict(r._mapping) for r in conn.execute(q)]

    @staticmethod
    def row(conn: sa.Connection, run_id: str) -> dict | None:
        r = conn.execute(sa.select(RUNS).where(RUNS.c.id == run_id)).first()
        return dict(r._mapping) if r is not None else None

    @staticmethod
    def output(conn: sa.Connection, run_id: str) -> str:
        return ''.join(conn.execute(sa.select(OUTPUT.c.text).where(OUTPUT.c.run == run_id)
                                    .order_by(OUTPUT.c.seq)).scalars())

    # --- deleting (on the store's thread) -----------------------------------------------------

    def delete(self, conn: sa.Connection, ids: list[str]) -> int:
        """Runs, their output and their recordings; not a run going now."""
        ids = [i for i in ids if i not in self.going]
        if not ids:
            return 0
        for path in conn.execute(sa.select(RUNS.c.recording).where(RUNS.c.id.in_(ids))).scalars():
            folder = Path(path).parent if path else None
            if folder is not None and folder.name.startswith('rec-'):   # the recording's bag directory
                shutil.rmtree(folder, ignore_errors=True)
        conn.execute(OUTPUT.delete().where(OUTPUT.c.run.in_(ids)))
        return conn.execute(RUNS.delete().where(RUNS.c.id.in_(ids))).rowcount

    def delete_person(self, conn: sa.Connection, person: str) -> int:
        """Every ended run of one person (their key or their name)."""
        ids = conn.execute(sa.select(RUNS.c.id).where(sa.or_(RUNS.c.owner == person, RUNS.c.who == person))).scalars()
        return self.delete(conn, list(ids))

    def prune(self, conn: sa.Connection, now: float | None = None, budget: int | None = None,
              reserved: dict | None = None) -> int:
        """Retention: ended runs past --runs-keep-days, beyond each person's --runs-keep-count
        newest, a person's oldest past their share (less what their runs going may take:
        ``reserved``), and while the archive passes ``budget`` (--runs-keep-bytes less what the runs
        going may take) the oldest of whoever keeps the most."""
        now = time.time() if now is None else now
        budget = self.keep_bytes if budget is None else budget
        reserved = reserved or {}
        # no run lasts LOST_AFTER (--max-timeout is at most an hour): one that never ended went with its gateway
        conn.execute(RUNS.update().where(RUNS.c.ended.is_(None), RUNS.c.started < now - LOST_AFTER).values(
            state='interrupted', ended=RUNS.c.started, reason='the gateway stopped before the run ended'))
        size = (sa.func.length(RUNS.c.source) + RUNS.c.output_bytes + RUNS.c.recording_bytes).label('size')
        rows = conn.execute(sa.select(RUNS.c.id, RUNS.c.owner, RUNS.c.started, size)
                            .where(RUNS.c.ended.is_not(None)).order_by(RUNS.c.started.desc())).all()
        gone, counts, held, kept = [], {}, {}, {}
        for run_id, owner, started, bytes_ in rows:                  # newest first
            counts[owner] = counts.get(owner, 0) + 1
            size = bytes_ or 0
            share = self.share - reserved.get(owner, 0) if owner is not None else budget
            if started < now - self.keep_days * 86400 or counts[owner] > self.keep_count \
                    or held.get(owner, 0) + size > share:
                gone.append(run_id)
            else:
                held[owner] = held.get(owner, 0) + size
                kept.setdefault(owner, []).append((run_id, size))    # newest first
        total = sum(held.values())
        while total > budget and total > 0:      # the oldest run of whoever keeps the most goes first
            owner = max((o for o in kept if kept[o]), key=lambda o: held[o])
            run_id, size = kept[owner].pop()
            held[owner] -= size
            total -= size
            gone.append(run_id)
        if gone:
            log.info('run archive: %d runs past retention deleted', len(gone))
        return self.delete(conn, gone) if gone else 0

    def _schedule_prune(self) -> None:
        if self.pruner is None:
            def again():
                self.pruner = None
                self.store.submit(self.prune)
                self._schedule_prune()
            self.pruner = asyncio.get_running_loop().call_later(PRUNE_EVERY, again)

    def close(self) -> None:
        for handle in (self.timer, self.pruner):
            if handle is not None:
                handle.cancel()
        self.flush()
