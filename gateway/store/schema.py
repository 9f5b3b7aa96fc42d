"""The store's schema, versioned: the alembic versions in ``migrations/versions/`` bring a database to
the newest when the store opens (``upgrade``), so an upgrade of rosgate that changes a table keeps a
school's data. A database made by a release before versions (tables, no ``alembic_version``) is taken
as it is: the first version creates only what is missing, and the versions after it change the rest.

Several gateways of a fleet may open one PostgreSQL at the same moment: the upgrade runs in one
transaction under an advisory lock, so one of them upgrades and the others find it done.
The tables' declarations (``METADATA``, where each feature keeps its own) must match the newest
version: tests/store/test_migrations.py compares them, so a change without its version fails there.

May import: nothing of the gateway.
"""

from __future__ import annotations

from pathlib import Path

import sqlalchemy as sa
from alembic import command
from alembic.config import Config
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory

MIGRATIONS = Path(__file__).with_name('migrations')
UPGRADE_KEY = 0x726F7369   # the advisory lock around an upgrade ("rosi")


def config() -> Config:
    cfg = Config()
    cfg.set_main_option('script_location', str(MIGRATIONS))
    return cfg


def head() -> str:
    """The newest version this rosgate knows."""
    return ScriptDirectory.from_config(config()).get_current_head()


def revision(conn: sa.Connection) -> str | None:
    """The version a database is at (None: no version yet)."""
    return MigrationContext.configure(conn).get_current_revision()


def upgrade(engine: sa.Engine) -> str:
    """Brings the database to ``head()``, in one transaction; returns the version it is at."""
    cfg = config()
    with engine.begin() as conn:
        if conn.dialect.name == 'postgresql':
            conn.execute(sa.text('SELECT pg_advisory_xact_lock(:key)'), {'key': UPGRADE_KEY})
        cfg.attributes['connection'] = conn
        command.upgrade(cfg, 'head')
        return revision(conn)
