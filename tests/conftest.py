"""The test suite's configuration: the shared fixtures and helpers live in tests/support/ (a plugin)."""

pytest_plugins = ['tests.support.fixtures']
