"""The CAN tier fixtures of tests/can/conftest.py (`can_tier`, `can_bus`), here too: one choice of
tier per session, named on the terminal."""
import importlib.util
from pathlib import Path

_spec = importlib.util.spec_from_file_location("can_tier_fixtures", Path(__file__).parents[1] / "can" / "conftest.py")
_fixtures = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_fixtures)

can_tier, can_bus = _fixtures.can_tier, _fixtures.can_bus
