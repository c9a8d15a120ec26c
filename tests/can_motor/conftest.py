"""Fixtures of the CAN motor node's tests; the helpers live in motor_bench.py."""
import pytest

from motor_bench import Bench


@pytest.fixture
def bench():
    """A CanMotor with the three-joint map of motor_bench, alone in an engine in virtual time."""
    return Bench()
