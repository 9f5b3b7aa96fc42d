"""The fleet's shared state as rows: ``fleet_state`` (a Stop in force, a Release, a signed-out session, the
walk-in queue: what must hold across gateways) and ``fleet_gateways`` (each live gateway and how far it has
read, so a logout is answered once every gateway knows).

Revision ID: 0002
Revises: 0001
"""
from alembic import op
import sqlalchemy as sa

revision = '0002'
down_revision = '0001'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        'fleet_state',
        sa.Column('kind', sa.String(16), nullable=False),
        sa.Column('name', sa.String(200), nullable=False),
        sa.Column('value', sa.Text(), nullable=False),
        sa.Column('gateway', sa.String(32), nullable=False),
        sa.Column('at', sa.Float(), nullable=False),
        sa.Column('until', sa.Float(), nullable=True),
        sa.PrimaryKeyConstraint('kind', 'name'))
    op.create_table(
        'fleet_gateways',
        sa.Column('id', sa.String(32), nullable=False),
        sa.Column('expires', sa.Float(), nullable=False),
        sa.Column('seen', sa.Float(), nullable=False),
        sa.Column('started', sa.Float(), nullable=False),
        sa.PrimaryKeyConstraint('id'))


def downgrade() -> None:
    op.drop_table('fleet_gateways')
    op.drop_table('fleet_state')
