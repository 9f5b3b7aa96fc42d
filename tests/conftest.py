"""The test suite's configuration: the shared fixtures and helpers live in tests/support/, loaded here
as plugins (fixtures; schedule, which spreads the files over parallel test processes)."""

pytest_plugins = ['tests.support.fixtures', 'tests.support.schedule']
