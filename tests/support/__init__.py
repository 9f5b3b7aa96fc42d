"""What every test folder shares, in one place: started gateways (process), waiting with a deadline
(wait), HTTP requests (http), roslibpy clients (ros), tokens (auth), robot-side runs (runs), the IDE
in Chromium (ide), the pages' state as tests see it (page_state), raw websocket clients (rawclient, rawsocket, wsclient), the test camera (camera),
an emulated home link (netlink), NaN-aware comparison (values), a PostgreSQL server (postgres) and
the cases of a fleet of gateways on it (fleet).

Tests import helpers from here only, never from another test module or a conftest; the shared
fixtures live in tests/support/fixtures.py, registered by tests/conftest.py (``pytest_plugins``).
"""
