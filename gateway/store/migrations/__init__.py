"""The store's schema versions (alembic): ``env.py`` runs them on the store's connection, one file per
version in ``versions/``. Made with ``alembic revision`` (``script.py.mako``), written by hand: a version
says what changes and never imports the tables it changes (they move on, the version stays)."""
