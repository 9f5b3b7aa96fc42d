"""The test suite's configuration: the shared fixtures and helpers live in tests/support/, loaded here
as plugins (fixtures; schedule, which spreads the files over parallel test processes). The cases
shared by test modules of several folders (tests/support/fleet.py) have their asserts explained as
a test module's are."""

import pytest

pytest.register_assert_rewrite('tests.support.fleet')

pytest_plugins = ['tests.support.fixtures', 'tests.support.schedule', 'tests.support.cost']
