"""alembic's entry: the versions run on the connection ``schema.upgrade`` hands over (no ini file, no
URL of its own), in its transaction; SQLite alters tables in batches (copy and move)."""

from alembic import context

connection = context.config.attributes['connection']
context.configure(connection=connection, render_as_batch=True, transaction_per_migration=False)
with context.begin_transaction():
    context.run_migrations()
