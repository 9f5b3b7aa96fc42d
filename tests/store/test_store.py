"""The one store: SQLite with WAL by default, work on its own thread, kept across a reopen."""

from __future__ import annotations

import asyncio
import threading

import sqlalchemy as sa

from gateway.store import Store

NOTES = sa.Table('test_store_notes', sa.MetaData(), sa.Column('id', sa.Integer, primary_key=True),
                 sa.Column('text', sa.String(200), nullable=False))


def test_sqlite_store_keeps_rows_across_a_reopen(tmp_path):
    url = f'sqlite:///{tmp_path}/sub/rosgate.db'
    store = Store(url)
    NOTES.create(store.engine)
    caller = threading.get_ident()

    def write(conn):
        conn.execute(NOTES.insert(), [{'text': 'a'}, {'text': 'b'}])
        return threading.get_ident()

    worker = asyncio.run(store.run(write))
    assert worker != caller                                   # the loop's thread never waits on the disk
    assert store.run_now(lambda c: c.execute(sa.text('PRAGMA journal_mode')).scalar()) == 'wal'
    assert store.size() > 0
    store.close()

    again = Store(url)
    rows = again.run_now(lambda c: [r.text for r in c.execute(sa.select(NOTES).order_by(NOTES.c.id))])
    again.close()
    assert rows == ['a', 'b']


def test_a_failed_write_is_rolled_back_and_the_store_goes_on(tmp_path):
    store = Store(f'sqlite:///{tmp_path}/rosgate.db')
    NOTES.create(store.engine)

    def half(conn):
        conn.execute(NOTES.insert(), [{'text': 'kept?'}])
        conn.execute(NOTES.insert(), [{'text': None}])        # NOT NULL: the whole transaction goes

    store.submit(half)
    count = asyncio.run(store.run(lambda c: c.execute(sa.select(sa.func.count()).select_from(NOTES)).scalar()))
    store.close()
    assert count == 0
