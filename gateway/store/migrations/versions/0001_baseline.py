"""The tables as rosgate 0.1 (release 44) made them, created where missing.

A database of that release has its tables and no version: this version creates none of them again and
marks the database as at 0001, so the versions after it change what that release left. A new database
gets every table here.

Revision ID: 0001
Revises:
"""
from alembic import op
import sqlalchemy as sa

revision = '0001'
down_revision = None
branch_labels = None
depends_on = None


def tables() -> list[tuple[str, tuple, dict, list[tuple]]]:
    """(name, columns and constraints, table options, indexes as (name, columns, unique))."""
    S, F, I, B, T, BI = sa.String, sa.Float, sa.Integer, sa.Boolean, sa.Text, sa.BigInteger
    col = sa.Column
    return [
        ('ags_links', (
            col('person', S(64), nullable=False), col('resource_link', S(255), nullable=False),
            col('issuer', S(255), nullable=False), col('client_id', S(255), nullable=False),
            col('subject', S(255), nullable=False), col('lineitem', S(1000), nullable=False),
            col('exercise', S(100), nullable=True), col('scopes', S(1000), nullable=False),
            col('launched', F(), nullable=False),
            sa.PrimaryKeyConstraint('person', 'resource_link')), {}, []),
        ('ags_outbox', (
            col('attempt_id', S(128), nullable=False), col('person', S(64), nullable=False),
            col('resource_link', S(255), nullable=False), col('score', F(), nullable=False),
            col('comment', S(200), nullable=True), col('created', F(), nullable=False),
            col('tries', I(), nullable=False), col('next_try', F(), nullable=False),
            col('posted', F(), nullable=True), col('last_error', S(500), nullable=True),
            sa.PrimaryKeyConstraint('attempt_id')), {}, []),
        ('bookings', (
            col('id', I(), autoincrement=True, nullable=False), col('station', S(100), nullable=False),
            col('person', S(200), nullable=False), col('name', S(200), nullable=False),
            col('start_at', F(), nullable=False), col('end_at', F(), nullable=False),
            col('created_at', F(), nullable=False),
            sa.PrimaryKeyConstraint('id')), {}, [('bookings_by_station', ['station', 'start_at'], False)]),
        ('exercise_attempts', (
            col('id', I(), autoincrement=True, nullable=False), col('attempt', S(64), nullable=False),
            col('exercise', S(100), nullable=False), col('person', S(200), nullable=False),
            col('name', S(200), nullable=False), col('station', S(100), nullable=False),
            col('passed', B(), nullable=False), col('score', F(), nullable=False),
            col('why', S(20), nullable=False), col('started_at', F(), nullable=False),
            col('ended_at', F(), nullable=False), col('program', T(), nullable=False),
            col('recording', S(200), nullable=True),
            sa.PrimaryKeyConstraint('id'), sa.UniqueConstraint('attempt')), {},
         [('ix_exercise_attempts_exercise', ['exercise'], False), ('ix_exercise_attempts_person', ['person'], False)]),
        ('fleet_holds', (
            col('kind', S(16), nullable=False), col('name', S(200), nullable=False),
            col('person', S(200), nullable=False), col('who', S(300), nullable=False),
            col('gateway', S(32), nullable=False), col('expires', F(), nullable=False),
            sa.PrimaryKeyConstraint('kind', 'name')), {}, []),
        ('history_minutes', (
            col('series', I(), nullable=False), col('t', BI(), nullable=False), col('n', I(), nullable=False),
            col('vmin', F(), nullable=False), col('vmean', F(), nullable=False), col('vmax', F(), nullable=False),
        ), {}, [('history_minutes_series_t', ['series', 't'], False)]),
        ('history_points', (
            col('series', I(), nullable=False), col('t', BI(), nullable=False), col('v', F(), nullable=False),
            sa.PrimaryKeyConstraint('series', 't', name='history_points_pk')), {'sqlite_with_rowid': False}, []),
        ('history_series', (
            col('id', I(), nullable=False), col('topic', S(255), nullable=False), col('field', S(255), nullable=False),
            sa.PrimaryKeyConstraint('id'), sa.UniqueConstraint('topic', 'field', name='history_series_topic_field')),
         {}, []),
        ('lti_courses', (
            col('url', S(1000), nullable=False), col('issuer', S(255), nullable=False),
            col('client_id', S(255), nullable=False), col('context', S(255), nullable=False),
            col('title', S(255), nullable=False), col('fetched', F(), nullable=False),
            sa.PrimaryKeyConstraint('url')), {}, []),
        ('lti_roster', (
            col('issuer', S(255), nullable=False), col('context', S(255), nullable=False),
            col('person', S(64), nullable=False), col('name', S(100), nullable=False),
            col('roles', S(1000), nullable=False), col('status', S(20), nullable=False),
            col('fetched', F(), nullable=False),
            sa.PrimaryKeyConstraint('issuer', 'context', 'person')), {}, []),
        ('people', (
            col('owner', S(100), nullable=False), col('name', S(200), nullable=False),
            col('role', S(16), nullable=False), col('kind', S(16), nullable=False), col('seen', F(), nullable=False),
            sa.PrimaryKeyConstraint('owner')), {}, []),
        ('run_output', (
            col('run', S(16), nullable=False), col('seq', I(), nullable=False), col('text', T(), nullable=False),
            sa.PrimaryKeyConstraint('run', 'seq', name='run_output_pk')), {}, []),
        ('runs', (
            col('id', S(16), nullable=False), col('name', S(64), nullable=False), col('kind', S(32), nullable=False),
            col('owner', S(255), nullable=True), col('who', S(255), nullable=True), col('ns', S(255), nullable=False),
            col('started', F(), nullable=False), col('ended', F(), nullable=True), col('state', S(16), nullable=False),
            col('exit_code', I(), nullable=True), col('reason', T(), nullable=True), col('source', T(), nullable=False),
            col('output_bytes', BI(), nullable=False), col('output_seen', BI(), nullable=False),
            col('cut', B(), nullable=False), col('recording', T(), nullable=True),
            col('recording_bytes', BI(), nullable=False),
            sa.PrimaryKeyConstraint('id')), {}, [('runs_owner_started', ['owner', 'started'], False)]),
        ('sessions', (
            col('id_hash', S(64), nullable=False), col('name', S(200), nullable=False),
            col('role', S(16), nullable=False), col('kind', S(16), nullable=False),
            col('owner', S(100), nullable=False), col('created', F(), nullable=False),
            col('expires', F(), nullable=False),
            sa.PrimaryKeyConstraint('id_hash')), {}, []),
    ]


def upgrade() -> None:
    there = set(sa.inspect(op.get_bind()).get_table_names())
    for name, columns, options, indexes in tables():
        if name in there:
            continue
        op.create_table(name, *columns, **options)
        for index, on, unique in indexes:
            op.create_index(index, name, on, unique=unique)


def downgrade() -> None:
    for name, *_ in reversed(tables()):
        op.drop_table(name)
