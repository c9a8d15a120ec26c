"""A program made runnable on one robot, and the state of running it (what preemption saves).

`compile_program` resolves joint keys to indices and compiles every interrupt and feedback
expression against the interpreter's inputs; anything this robot cannot run is a
`ProgramFault` naming the field. `ProgramRun` is where a program stands: behaviour, atom, and
the running atom's `AtomRun` (time spent, start and goal positions, feedback integral). Keeping a
`ProgramRun` aside is all it takes to resume the program later.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from channels.mdl import Pose, Program
from iotad.esprit.errors import EspritError
from iotad.esprit.expressions import CompiledExpression, compile_expression
from iotad.kernel.types import Bool, Float

from .config import Robot, SensorLayout


class ProgramFault(Exception):
    """The program cannot run (here, or from this point on); `str()` says why."""


class MissingInput(Exception):
    """An input the atom reads has no usable value now: the motors are held until it has."""

    def __init__(self, name: str, why: str, reason: str = ""):
        super().__init__(f"{name}: {why}")
        self.name, self.why = name, why
        self.key = (name, reason or why)   # what stays the same while the same cause lasts


@dataclass
class CompiledAtom:
    behaviour: int
    index: int
    kind: str
    T: float | None
    ticks: int | None                       # whole ticks it lasts (T rounded up), None: no end
    goal: dict[int, float] = field(default_factory=dict)       # ramp, minimum_jerk
    pose: Pose | None = None
    velocity: dict[int, float] = field(default_factory=dict)
    amplitude: dict[int, float] = field(default_factory=dict)
    frequency: float = 0.0
    phase: float = 0.0
    gains: list[tuple[int, CompiledExpression, float]] = field(default_factory=list)
    xi: CompiledExpression | None = None


@dataclass
class CompiledProgram:
    program: Program
    xi: CompiledExpression | None
    behaviour_xi: list[CompiledExpression | None]
    atoms: list[list[CompiledAtom]]


class ExpressionCache:
    """Compiled expressions of one interpreter (its inputs fix their meaning), by text."""

    LIMIT = 512

    def __init__(self, layout: SensorLayout, joints: int):
        self.scope = layout.scope(joints)
        self._compiled: dict[tuple[str, str], CompiledExpression] = {}

    def get(self, text: str, expect, where: str) -> CompiledExpression:
        key = (text, expect.name)
        found = self._compiled.get(key)
        if found is None:
            try:
                found = compile_expression(text, self.scope, expect, filename=where)
            except EspritError as exc:
                raise ProgramFault(str(exc)) from None
            if len(self._compiled) >= self.LIMIT:
                self._compiled.clear()
            self._compiled[key] = found
        return found


def compile_program(program: Program, robot: Robot, cache: ExpressionCache) -> CompiledProgram:
    def condition(text: str, where: str) -> CompiledExpression | None:
        return cache.get(text, Bool, where) if text else None

    def joints(pairs, where: str) -> dict[int, float]:
        out = {}
        for key, value in pairs:
            index = robot.joint_index(key)
            if index is None:
                raise ProgramFault(f"{where}: unknown joint {key!r}; this robot has {list(robot.joints)} "
                                   f"(or indices 0..{robot.size - 1})")
            if index in out:  # by name and by index: which one was meant is not for us to guess
                raise ProgramFault(f"{where}: joint {robot.joints[index]!r} is given twice ({key!r} is it too)")
            out[index] = value
        return out

    behaviours, behaviour_xi = [], []
    for b, behaviour in enumerate(program.behaviours):
        behaviour_xi.append(condition(behaviour.xi, f"behaviours[{b}].xi"))
        atoms = []
        for a, atom in enumerate(behaviour.atoms):
            where = f"behaviours[{b}].atoms[{a}]"
            u = atom.u
            if atom.T is not None and not math.isfinite(atom.T / robot.period):
                raise ProgramFault(f"{where}.T: {atom.T:g} s is more ticks of {robot.period:g} s than can be counted")
            ticks = None if atom.T is None else max(1, math.ceil(atom.T / robot.period - 1e-9))
            compiled = CompiledAtom(b, a, u.kind, atom.T, ticks, pose=u.pose, frequency=u.frequency, phase=u.phase,
                                    goal=joints(u.target, f"{where}.u.target"),
                                    velocity=joints(u.velocity, f"{where}.u.velocity"),
                                    amplitude=joints(u.amplitude, f"{where}.u.amplitude"),
                                    xi=condition(atom.xi, f"{where}.xi"))
            for g, term in enumerate(atom.k):
                index = robot.joint_index(term.joint)
                if index is None:
                    raise ProgramFault(f"{where}.k[{g}].joint: unknown joint {term.joint!r}; this robot has "
                                       f"{list(robot.joints)} (or indices 0..{robot.size - 1})")
                compiled.gains.append((index, cache.get(term.sensor, Float, f"{where}.k[{g}].sensor"), term.gain))
            atoms.append(compiled)
        behaviours.append(atoms)
    return CompiledProgram(program, condition(program.xi, "xi"), behaviour_xi, behaviours)


def _shape(kind: str, x: float) -> float:
    """Fraction of the way to the goal at fraction x of the duration."""
    if kind == "ramp":
        return x
    return x * x * x * (10.0 + x * (-15.0 + 6.0 * x))  # minimum jerk (Flash and Hogan)


class AtomRun:
    """One atom being run: `reference(tau)` is u(tau) plus the feedback integral, per joint.

    u is anchored at the command the atom started from. On a resume the anchor moves to the
    command the arm holds then (`reanchor`), so the motion is continuous: a ramp or minimum-jerk
    keeps its goal and finishing time for the joints it names (the offset fades out along the
    profile) and holds the others where they are, the other kinds carry on shifted by the offset. If the arm was held still meanwhile the offset is zero and
    the atom finishes exactly the trajectory it would have, later.
    """

    def __init__(self, atom: CompiledAtom, start: list[float], goal: list[float] | None):
        self.atom = atom
        self.ticks = 0                      # ticks run so far (time in the atom = ticks * period)
        self.base = list(start)
        self.goal = goal                    # per joint, for ramp / minimum_jerk
        n = len(start)
        self.offset = [0.0] * n
        self.anchor = 0.0                   # time at which `offset` was taken
        self.feedback = [0.0] * n           # the integral of k(y), per joint
        self.velocity = [atom.velocity.get(j, 0.0) for j in range(n)]
        self.amplitude = [atom.amplitude.get(j, 0.0) for j in range(n)]
        self.short: tuple[float, int] | None = None  # (gap, joint): the velocity limit's lag at the last step

    def open_loop(self, tau: float) -> list[float]:
        atom, base = self.atom, self.base
        kind = atom.kind
        if kind in ("ramp", "minimum_jerk"):
            T = atom.T
            s = _shape(kind, min(1.0, tau / T))
            left = 1.0 - _shape(kind, min(1.0, self.anchor / T))
            fade = (1.0 - s) / left if left > 1e-12 else 0.0
            return [b + (g - b) * s + o * fade for b, g, o in zip(base, self.goal, self.offset)]
        if kind == "velocity":
            return [b + v * tau + o for b, v, o in zip(base, self.velocity, self.offset)]
        if kind == "sine":
            angle = 2.0 * math.pi * atom.frequency * tau + atom.phase
            wave = math.sin(angle) - math.sin(atom.phase)
            return [b + a * wave + o for b, a, o in zip(base, self.amplitude, self.offset)]
        return [b + o for b, o in zip(base, self.offset)]

    def reanchor(self, command: list[float], tau: float) -> None:
        if self.goal is not None and self.atom.pose is None:
            # joints its target leaves out hold where they are now, not where the atom started:
            # what moved them while it was preempted is not undone
            for j, c in enumerate(command):
                if j not in self.atom.goal:
                    # the open-loop part holds there: the feedback integral, in the command already,
                    # is added to it again below, so it is taken out here (not counted twice)
                    self.base[j] = self.goal[j] = c - self.feedback[j]
        self.anchor = tau
        self.offset = [0.0] * len(command)
        now = self.open_loop(tau)
        self.offset = [c - f - u for c, f, u in zip(command, self.feedback, now)]


class ProgramRun:
    """Where a program stands: behaviour, atom, and the atom under way (None until it starts)."""

    def __init__(self, compiled: CompiledProgram):
        self.compiled = compiled
        self.program = compiled.program
        self.behaviour = 0
        self.atom = 0
        self.current: AtomRun | None = None
        self.holding: tuple | None = None  # why the motors are held (MissingInput.key), if they are
        self.unread: tuple | None = None   # why a wait's interrupt cannot be read (MissingInput.key), if so

    @property
    def spec(self) -> CompiledAtom:
        return self.compiled.atoms[self.behaviour][self.atom]

    def next_atom(self) -> bool:
        """On to the next atom (the next behaviour after the last); False when none is left."""
        self.current = None
        self.atom += 1
        if self.atom >= len(self.compiled.atoms[self.behaviour]):
            return self.next_behaviour()
        return True

    def next_behaviour(self) -> bool:
        self.current = None
        self.behaviour += 1
        self.atom = 0
        return self.behaviour < len(self.compiled.atoms)

    def atom_count(self) -> int:
        return sum(len(atoms) for atoms in self.compiled.atoms)
