"""Fixtures of this folder; the helpers live in sim_helpers.py (a module name of its own:
`from conftest import` would find another folder's conftest when folders run together)."""
from sim_helpers import armed_axis, make_sim  # noqa: F401 - fixtures
