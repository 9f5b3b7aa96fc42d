"""LTI Dynamic Registration: the admins' one-time registration URLs and the platforms registered by it
(``gateway.auth.lti_dynamic``), created where missing.

Revision ID: 0003
Revises: 0002
"""
from alembic import op
import sqlalchemy as sa

revision = '0003'
down_revision = '0002'
branch_labels = None
depends_on = None


def tables() -> list[tuple[str, tuple]]:
    S, F = sa.String, sa.Float
    col = sa.Column
    return [
        ('lti_platforms', (
            col('issuer', S(255), nullable=False), col('client_id', S(255), nullable=False),
            col('deployment_ids', S(1000), nullable=False), col('auth_login_url', S(1000), nullable=False),
            col('key_set_url', S(1000), nullable=False), col('auth_token_url', S(1000), nullable=True),
            col('product', S(100), nullable=False), col('scopes', S(2000), nullable=False),
            col('registered', F(), nullable=False), col('registered_by', S(100), nullable=False),
            sa.PrimaryKeyConstraint('issuer', 'client_id'))),
        ('lti_registration_links', (
            col('digest', S(64), nullable=False), col('made_by', S(100), nullable=False),
            col('expires', F(), nullable=False), col('used', F(), nullable=True),
            sa.PrimaryKeyConstraint('digest'))),
    ]


def upgrade() -> None:
    there = set(sa.inspect(op.get_bind()).get_table_names())
    for name, columns in tables():
        if name not in there:
            op.create_table(name, *columns)


def downgrade() -> None:
    for name, _ in reversed(tables()):
        op.drop_table(name)
