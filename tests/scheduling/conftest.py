"""Fixtures of this folder; the helpers live in scheduling_helpers.py (a module name of its own:
`from conftest import` would find another folder's conftest when folders run together)."""
from scheduling_helpers import resume  # noqa: F401 - fixtures
