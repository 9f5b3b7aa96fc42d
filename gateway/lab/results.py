"""The attempts' results, kept in the gateway's store (table ``exercise_attempts``).

One row per attempt: who (``person``: the identity's key, ``name`` as pages show it), which exercise,
the attempt's id (unique: a grade is never posted twice for one attempt), pass/fail, the score 0–1,
when it began and ended, why it ended (``goal``, ``time``, ``stopped``, ``failed``) and the program as
it ran (its text, at most MAX_PROGRAM bytes).
"""

from __future__ import annotations

import sqlalchemy as sa

from ..store import METADATA

MAX_PROGRAM = 256 * 1024

TABLE = sa.Table(
    'exercise_attempts', METADATA,
    sa.Column('id', sa.Integer, primary_key=True, autoincrement=True),
    sa.Column('attempt', sa.String(64), nullable=False, unique=True),
    sa.Column('exercise', sa.String(100), nullable=False, index=True),
    sa.Column('person', sa.String(200), nullable=False, index=True),
    sa.Column('name', sa.String(200), nullable=False),
    sa.Column('station', sa.String(100), nullable=False),
    sa.Column('passed', sa.Boolean, nullable=False),
    sa.Column('score', sa.Float, nullable=False),
    sa.Column('why', sa.String(20), nullable=False),
    sa.Column('started_at', sa.Float, nullable=False),
    sa.Column('ended_at', sa.Float, nullable=False),
    sa.Column('program', sa.Text, nullable=False),
    sa.Column('recording', sa.String(200), nullable=True),
)

COLUMNS = ('attempt', 'exercise', 'person', 'name', 'station', 'passed', 'score', 'why',
           'started_at', 'ended_at', 'program', 'recording')


def insert(conn: sa.Connection, row: dict) -> None:
    conn.execute(TABLE.insert().values(**{k: row[k] for k in COLUMNS}))


def select(conn: sa.Connection, *, person: str | None = None, exercise: str | None = None,
           attempt: str | None = None) -> list[dict]:
    q = TABLE.select().order_by(TABLE.c.ended_at)
    if attempt is not None:
        q = q.where(TABLE.c.attempt == attempt)
    if person is not None:
        q = q.where(TABLE.c.person == person)
    if exercise is not None:
        q = q.where(TABLE.c.exercise == exercise)
    return [{k: r._mapping[k] for k in COLUMNS} for r in conn.execute(q)]


def best_and_last(rows: list[dict]) -> dict:
    """{(person, exercise): {'best': row, 'last': row, 'attempts': n}} (rows in time order)."""
    out: dict = {}
    for row in rows:
        entry = out.setdefault((row['person'], row['exercise']), {'best': row, 'last': row, 'attempts': 0})
        entry['attempts'] += 1
        entry['last'] = row
        if (row['score'], row['passed']) > (entry['best']['score'], entry['best']['passed']):
            entry['best'] = row
    return out
