"""The store's schema versions (gateway/store/schema.py, alembic): a database of the last release before
versions keeps its rows and reaches the newest schema; a new database is made by the versions alone;
the tables as the code declares them are the newest version's (a table changed without a version fails
here); gateways of a fleet opening one PostgreSQL at the same moment upgrade it once."""

from __future__ import annotations

import importlib
import pkgutil
import threading
from pathlib import Path

import pytest
import sqlalchemy as sa
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext

import gateway
from gateway.store import METADATA, Store, schema
from tests.support.postgres import postgres_server

HERE = Path(__file__).parent
postgres = pytest.fixture(scope='module')(postgres_server)


def declared() -> sa.MetaData:
    """METADATA with every table the gateway declares: every module that may declare one, imported."""
    for module in pkgutil.walk_packages(gateway.__path__, 'gateway.'):
        if '.backends.rclpy' in module.name or '.migrations' in module.name or module.name == 'gateway.__main__':
            continue   # rclpy's needs rclpy; the versions are run by alembic; __main__ starts one
        importlib.import_module(module.name)
    return METADATA


def differences(url: str) -> list:
    engine = sa.create_engine(url)
    try:
        with engine.connect() as conn:
            found = compare_metadata(MigrationContext.configure(conn), declared())
    finally:
        engine.dispose()
    return [d for d in found if not (d[0] == 'remove_table' and d[1].name == 'alembic_version')]


def release_44(url: str, dialect: str) -> None:
    """The database as release 44 left it: its own DDL, then a row of each kind a school keeps."""
    engine = sa.create_engine(url)
    text = '\n'.join(line for line in (HERE / f'release44.{dialect}.sql').read_text().splitlines()
                     if not line.startswith('--'))
    statements = [s for s in text.split(';') if s.strip()]
    with engine.begin() as conn:
        for statement in statements:
            conn.exec_driver_sql(statement)
        conn.execute(sa.text("INSERT INTO sessions VALUES ('h1', 'Ada', 'operator', 'token', 'ada', 1.0, 9e9)"))
        conn.execute(sa.text("INSERT INTO bookings (station, person, name, start_at, end_at, created_at) "
                             "VALUES ('s01', 'ada', 'Ada', 10.0, 20.0, 1.0)"))
        conn.execute(sa.text("INSERT INTO exercise_attempts (attempt, exercise, person, name, station, passed, score,"
                             " why, started_at, ended_at, program, recording) VALUES ('a1', 'square', 'ada', 'Ada',"
                             " 's01', true, 1.0, 'passed', 1.0, 2.0, '{}', 'rec-1')"))
        conn.execute(sa.text("INSERT INTO history_series (id, topic, field) VALUES (1, '/turtle1/pose', 'x')"))
        conn.execute(sa.text("INSERT INTO history_points VALUES (1, 1000, 5.5)"))
    engine.dispose()


def kept(store: Store) -> tuple:
    def read(conn):
        return (conn.execute(sa.text('SELECT name, owner FROM sessions')).all(),
                conn.execute(sa.text('SELECT station, person FROM bookings')).all(),
                conn.execute(sa.text('SELECT attempt, passed, recording FROM exercise_attempts')).all(),
                conn.execute(sa.text('SELECT v FROM history_points')).all())
    return store.run_now(read)


def versions(url: str) -> tuple[str | None, list[str]]:
    engine = sa.create_engine(url)
    with engine.connect() as conn:
        at, tables = schema.revision(conn), sorted(sa.inspect(conn).get_table_names())
    engine.dispose()
    return at, tables


@pytest.mark.parametrize('kind', ['sqlite', 'postgresql'])
def test_a_release_44_database_keeps_its_rows_and_reaches_the_newest_schema(kind, tmp_path, request):
    url = f'sqlite:///{tmp_path}/rosgate.db' if kind == 'sqlite' else request.getfixturevalue('postgres')
    release_44(url, kind)
    assert versions(url)[0] is None                       # before versions: tables, no version
    store = Store(url)
    try:
        assert store.revision == schema.head()
        assert kept(store) == ([('Ada', 'ada')], [('s01', 'ada')], [('a1', True, 'rec-1')], [(5.5,)])
    finally:
        store.close()
    assert differences(url) == []                         # what the code declares, no more, no less
    store = Store(url)                                    # opened again: nothing to do, nothing lost
    try:
        assert store.revision == schema.head() and kept(store)[0] == [('Ada', 'ada')]
    finally:
        store.close()


def test_a_new_database_is_made_by_the_versions_alone(tmp_path):
    url = f'sqlite:///{tmp_path}/new.db'
    Store(url).close()
    at, tables = versions(url)
    assert at == schema.head()
    assert 'alembic_version' in tables and 'sessions' in tables
    assert differences(url) == []


def test_the_check_sees_a_table_changed_without_a_version(tmp_path):
    """The comparison above can fail: a column the versions do not make is reported."""
    url = f'sqlite:///{tmp_path}/drift.db'
    Store(url).close()
    extra = sa.Column('nickname', sa.String(40), nullable=True)
    table = declared().tables['people']
    table.append_column(extra)
    try:
        found = differences(url)
    finally:
        table._columns.remove(extra)
    assert [(d[0], d[3].name) for d in found] == [('add_column', 'nickname')]


def test_gateways_opening_one_postgresql_at_once_upgrade_it_once(postgres):
    engine = sa.create_engine(postgres)
    with engine.begin() as conn:   # a fresh database for this test
        conn.execute(sa.text('DROP SCHEMA public CASCADE'))
        conn.execute(sa.text('CREATE SCHEMA public'))
    engine.dispose()
    start, opened, failed = threading.Barrier(4), [], []

    def open_one():
        start.wait()
        try:
            store = Store(postgres)
            opened.append(store.revision)
            store.close()
        except Exception as exc:   # noqa: BLE001 — the failure is the finding
            failed.append(exc)

    threads = [threading.Thread(target=open_one) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=120)
    assert failed == [] and opened == [schema.head()] * 4
    assert differences(postgres) == []
