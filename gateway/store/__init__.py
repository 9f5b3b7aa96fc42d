"""What rosgate keeps across restarts, in one database: bookings, the robots' history, owners.

SQLAlchemy Core serves both kinds of place a school keeps things: SQLite in the gateway's data
directory by default (``$XDG_DATA_HOME/rosgate/rosgate.db``, WAL journal so that readers never
wait for the writer), or any URL SQLAlchemy speaks (``--db postgresql+psycopg://user@host/rosgate``)
for a fleet of gateways that shares one place (``fleet``: leases, claims, stops, sign-ins, the
timetable and one history, across gateways).

Features declare their tables on ``METADATA`` where they live, and the schema's versions
(``schema.py``, alembic) make them: a database is brought to the newest version when it opens. They reach
the database only through ``Store.run(fn)``: ``fn(connection)`` runs inside a transaction on the
store's one worker thread, so the event loop never waits on a disk or a network and writes never
race each other. ``Store.run_now(fn)`` is the same on the calling thread, for start-up and tests.

May import: ``settings`` only. Any role above the backends may use it.
"""

from __future__ import annotations

import asyncio
import logging
import os
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Callable, TypeVar

import sqlalchemy as sa

from ..settings import data_dir
from . import schema

log = logging.getLogger('rosgate.store')
METADATA = sa.MetaData()
T = TypeVar('T')


def default_url() -> str:
    return f"sqlite:///{data_dir('rosgate.db')}"


SECRET_KEYS = ('password', 'passwd', 'pwd', 'secret', 'token', 'key')   # query parameters masked in a shown URL


def _public(url: sa.engine.URL) -> str:
    """The URL as it may be shown: its password masked, in the user part and in the query too
    (libpq takes ``?password=``, ``?sslpassword=``)."""
    query = {k: ('***' if any(word in k.lower() for word in SECRET_KEYS) else v) for k, v in url.query.items()}
    return url.set(query=query).render_as_string(hide_password=True)


def pg_connect_args(role: str) -> dict:
    """libpq settings for each PostgreSQL connection of this gateway: a dead peer or a network that
    drops everything is noticed within seconds, not TCP's minutes; each named ``rosgate-PID-ROLE``
    (``application_name``: an operator finds a gateway's connections in ``pg_stat_activity``)."""
    return {'connect_timeout': 3, 'keepalives': 1, 'keepalives_idle': 2, 'keepalives_interval': 1,
            'keepalives_count': 2, 'tcp_user_timeout': 5000, 'application_name': f'rosgate-{os.getpid()}-{role}'}


class Store:
    """One database, opened once per gateway and brought to the newest schema version then."""

    def __init__(self, url: str | None = None):
        url = url or default_url()
        parsed = sa.engine.make_url(url)
        self.sqlite = parsed.get_backend_name() == 'sqlite'
        if self.sqlite and parsed.database and parsed.database != ':memory:':
            Path(parsed.database).parent.mkdir(parents=True, exist_ok=True)
            self.path: Path | None = Path(parsed.database)
        else:
            self.path = None
        self.url = _public(parsed)
        self.engine = sa.create_engine(parsed, future=True, pool_pre_ping=not self.sqlite, connect_args=(
            pg_connect_args('store') if parsed.get_backend_name() == 'postgresql' else {}))
        if self.sqlite:
            sa.event.listen(self.engine, 'connect', _sqlite_pragmas)
        self._worker = ThreadPoolExecutor(max_workers=1, thread_name_prefix='rosgate-store')
        self.revision = schema.upgrade(self.engine)
        log.info('store: %s (schema %s)', self.url, self.revision)

    async def run(self, fn: Callable[[sa.Connection], T]) -> T:
        """fn(connection) in a transaction on the store's thread; the loop goes on meanwhile."""
        return await asyncio.get_running_loop().run_in_executor(self._worker, self.run_now, fn)

    def submit(self, fn: Callable[[sa.Connection], object]) -> None:
        """fn(connection) on the store's thread, not awaited (batched writes); failures are logged."""
        def guarded():
            try:
                self.run_now(fn)
            except Exception:
                log.exception('store write failed')
        self._worker.submit(guarded)

    def run_now(self, fn: Callable[[sa.Connection], T]) -> T:
        with self.engine.begin() as conn:
            return fn(conn)

    def size(self) -> int:
        """Bytes the database takes on disk (SQLite: the file and its WAL)."""
        if self.path is not None:
            return sum(os.path.getsize(p) for p in (self.path, Path(f'{self.path}-wal'))
                       if os.path.exists(p))
        if self.engine.dialect.name == 'postgresql':
            return int(self.run_now(lambda c: c.execute(sa.text('SELECT pg_database_size(current_database())'))
                                    .scalar()))
        return 0

    def close(self) -> None:
        self._worker.shutdown(wait=True)
        self.engine.dispose()


def _sqlite_pragmas(dbapi_conn, _record) -> None:
    cur = dbapi_conn.cursor()
    cur.execute('PRAGMA journal_mode=WAL')
    cur.execute('PRAGMA synchronous=NORMAL')   # durable at each checkpoint; a crash loses at most the last writes
    cur.execute('PRAGMA busy_timeout=5000')
    cur.close()
