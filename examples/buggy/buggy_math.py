"""Plane geometry and a seeded random stream for Buggy's ESPRIT specs (extern functions)."""
import math


def wrap(angle: float) -> float:
    """The angle in (-pi, pi]."""
    return math.atan2(math.sin(angle), math.cos(angle))


def atan2(y: float, x: float) -> float:
    return math.atan2(y, x)


def hypot(x: float, y: float) -> float:
    return math.hypot(x, y)


def clamp(value: float, low: float, high: float) -> float:
    return min(high, max(low, value))


# A 31-bit linear congruential generator (the C library's constants): an IOTA keeps its state in
# an int, so the same seed gives the same wandering on every run and in every replay.
def lcg(state: int) -> int:
    return (1103515245 * state + 12345) % 2147483648


def uniform(state: int) -> float:
    """A number in [-1, 1) drawn from the generator's state."""
    return state / 1073741824.0 - 1.0


# ------------------------------------------------------------------ steering laws (body frame)
def follow(x: float, y: float, speed: float, gain: float, turn_max: float, near: float) -> dict:
    """Steer toward the crack point (x, y) while farther than `near`, then along the crack: the
    tangent closer to the current heading, blended with the bearing by distance."""
    bearing = math.atan2(y, x)
    tangents = (wrap(bearing - math.pi / 2), wrap(bearing + math.pi / 2))
    tangent = min(tangents, key=abs)
    blend = min(1.0, math.hypot(x, y) / near)
    heading = wrap(tangent + wrap(bearing - tangent) * blend)
    return {"speed": speed, "turn": clamp(gain * heading, -turn_max, turn_max), "why": "FOLLOW"}


def avoid(direction: float, speed: float, gain: float, turn_max: float) -> dict:
    """Turn away from a wall seen at `direction`; stop while still facing it (rotate in place)."""
    away = wrap(direction + math.pi)
    return {"speed": speed if abs(away) < math.pi / 3 else 0.0, "turn": clamp(gain * away, -turn_max, turn_max),
            "why": "AVOID"}
