"""The MDL interpreter IOTA: runs motion programs at the control rate into per-joint setpoints.

Every tick (1/rate s, on the engine's time grid) it takes the newest command, checks the
running program's interrupts (plan, behaviour, atom: outermost first) on the latest inputs,
steps the atom, u(t) + integral of k(y), and publishes the joints' setpoints, rate-limited and
within the joints' limits. Atom and program ends go out on `atom_end` and `program_end`;
anything that stops a program or holds the motors goes out on `fault`. docs/mdl.md is the
reference: channels, parameters, the program format and what each decision means.

Ticks sit on multiples of the period in engine time (`tick` waits until the next one), read
with `now()` (iotad.esprit.runtime) from its time bound and do-block: in virtual time that is
exactly every period; in real time a late tick does not push the later ones back (no drift),
and a stall longer than a period skips ticks and steps the motion by the time that passed.
"""
from __future__ import annotations

import functools
import math

from channels.joints import JOINT_SETPOINTS, JOINT_STATES, joint_setpoints, joint_states
from channels.mdl import (ATOM_END, MDL_FAULT, MDL_PROGRAM, MODE_JOINT, PROGRAM_END, SENSOR_READING, Program,
                          mode_program)
from channels.messages import MODE
from iotad.esprit.runtime import esprit_now
from iotad.kernel.api import Input, Internal, Iota, Output, Param

from .config import (DEFAULT_SENSORS, POSITION, XARM6_JOINTS, XARM6_LOWER, XARM6_MAX_VELOCITY, XARM6_UPPER,
                     robot_from, sensors_from)
from .kinematics import KinematicsError, kinematics_for
from .program_run import (AtomRun, CompiledExpression, ExpressionCache, MissingInput, ProgramFault, ProgramRun,
                          compile_program)

GRID_SLACK = 1e-6  # of a period: a tick computed as now + delay lands on the grid up to rounding
GOAL_SLACK = 1e-9  # rad (or m): a command this close to its reference is on it
BEFORE_NEXT_TICK = (0, lambda self: self._robot.period)  # every output's window


class _Inputs:
    """What expressions read: one attribute per sensor (a record of its named floats) and
    `position` (the measured joint positions)."""


class MdlInterpreter(Iota):
    """The interpreter for the six joints of the xArm6; `interpreter_class(n)` for n joints."""

    JOINTS = 6

    rate = Param(500.0)                     # ticks per second
    joints = Param(XARM6_JOINTS)            # joint names, in setpoint order
    lower = Param(XARM6_LOWER)              # joint limits (rad or m)
    upper = Param(XARM6_UPPER)
    max_velocity = Param(XARM6_MAX_VELOCITY)  # per joint, or one for all (per second)
    sensors = Param(DEFAULT_SENSORS)        # sensor[k]: name -> names of its floats
    K = Param(len(DEFAULT_SENSORS))         # number of sensor inputs (from `sensors` if not given)
    sensor_timeout = Param(0.1)             # an input older than this (s) is missing
    max_suspended = Param(8)                # preempted programs kept for resuming
    urdf = Param("xarm/xarm6_with_gripper.urdf")  # for pose targets (pybullet_data path or absolute)
    ee_link = Param("link6")
    ik_tolerance = Param(0.01)              # metres
    preload_ik = Param(False)               # load the URDF at start, not at the first pose
    tick_slack = Param(0.002)               # s a tick may come late in real time before it is a deadline miss

    mdl_command = Input(MDL_PROGRAM)
    mode_command = Input(MODE)              # the paper's mode {w, k}: its one-atom program
    joint_states = Input(JOINT_STATES)
    sensor = Input(SENSOR_READING, size="K")
    tick = Internal()
    setpoints = Output(JOINT_SETPOINTS)
    atom_end = Output(ATOM_END)
    program_end = Output(PROGRAM_END)
    fault = Output(MDL_FAULT)

    def __init__(self, name: str | None = None, **params):
        if "K" not in params:
            sensors = params.get("sensors", DEFAULT_SENSORS)
            params["K"] = len(sensors) if isinstance(sensors, dict) else 0
        super().__init__(name, **params)

    def init(self):
        self._robot = robot_from(self.joints, self.lower, self.upper, self.max_velocity, self.rate)
        if self._robot.size != self.JOINTS:
            raise ValueError(f"joints: {self._robot.size} names for an interpreter of {self.JOINTS} joints "
                             f"(use nodes.mdl_interp:mdl_interpreter, which picks the class)")
        self._layout = sensors_from(self.sensors)
        if self.K != len(self._layout.names):
            raise ValueError(f"K={self.K} but sensors names {len(self._layout.names)} inputs")
        if isinstance(self.sensor_timeout, bool) or not isinstance(self.sensor_timeout, (int, float)) \
                or not self.sensor_timeout > 0:
            raise ValueError(f"sensor_timeout: expected seconds > 0 (inf: never stale), got {self.sensor_timeout!r}")
        if isinstance(self.tick_slack, bool) or not isinstance(self.tick_slack, (int, float)) \
                or not 0 <= self.tick_slack < math.inf:
            raise ValueError(f"tick_slack: expected seconds >= 0, got {self.tick_slack!r}")
        if isinstance(self.max_suspended, bool) or not isinstance(self.max_suspended, int) or self.max_suspended < 0:
            raise ValueError(f"max_suspended: expected a whole number >= 0, got {self.max_suspended!r}")
        self._expressions = ExpressionCache(self._layout, self._robot.size)
        self._kinematics = kinematics_for(str(self.urdf), self._robot.joints, str(self.ee_link), float(self.ik_tolerance))
        if self.preload_ik:
            self._kinematics.load()
        self._inputs = _Inputs()
        self._now = 0.0
        # state
        self.tick_index = None          # the grid index of the last tick
        self.command = None             # the joints' commanded positions (None until joint_states)
        self.position = None            # measured, from joint_states
        self.position_time = -math.inf
        self.sensor_valid = [False] * self.K
        self.sensor_time = [-math.inf] * self.K
        self.incoming = None            # a command waiting for the next tick
        self.running = None             # ProgramRun
        self.began = False              # running started or resumed since the last step
        self.suspended = {}             # program id -> ProgramRun, oldest first
        self.waiting_reported = False
        self.out_setpoint = None
        self.out_atom_ends = []
        self.out_program_ends = []
        self.out_faults = []
        self._refused: dict[str, str] = {}  # program id -> why: a mode refused when it came

    # ------------------------------------------------------------------ inputs
    @mdl_command.input
    def on_mdl_command(self, program):
        self._command_arrived(program)

    @mode_command.input
    def on_mode_command(self, mode):
        program = mode_program(mode.w, mode.k)
        robot, joint = self._robot, int(MODE_JOINT)
        if not robot.lower[joint] <= mode.w <= robot.upper[joint]:
            # a goal outside the limits is refused, as a ramp's is, not driven into the limit
            self._refused[program.id] = (f"behaviours[0].atoms[0]: the mode's setpoint w = {mode.w:.6g} of joint "
                                         f"{robot.joints[joint]} is outside its limits "
                                         f"[{robot.lower[joint]:g}, {robot.upper[joint]:g}]")
        self._command_arrived(program)

    @joint_states.input
    def on_joint_states(self, states):
        self.position = list(states.position)
        self.position_time = esprit_now()
        self._inputs.position = self.position

    @sensor.input
    def on_sensor(self, i, reading):
        layout = self._layout
        setattr(self._inputs, layout.names[i], layout.types[i](*reading.value[:len(layout.fields[i])]))
        self.sensor_valid[i] = reading.valid
        self.sensor_time[i] = esprit_now()

    # ------------------------------------------------------------------ the control tick
    # The engine evaluates a window's lower bound, then its upper one, at the same instant: the
    # upper reuses the lower's delay (now() walks the stack: it is not free at 500 Hz).
    @tick.action(within=(lambda self: self._until_next_tick(), lambda self: self._delay + self.tick_slack))
    def on_tick(self):
        self._tick(esprit_now())

    # Every output goes out before the next tick: a spec that allowed any delay would let a legal
    # schedule (the random policy's, `iotad run --seed`) fall behind without limit.
    @setpoints.action(value=lambda self: self.out_setpoint, when=lambda self: self.out_setpoint is not None,
                      within=BEFORE_NEXT_TICK)
    def sent_setpoints(self):
        self.out_setpoint = None

    @atom_end.action(value=lambda self: self.out_atom_ends[0], when=lambda self: len(self.out_atom_ends) > 0,
                     within=BEFORE_NEXT_TICK)
    def sent_atom_end(self):
        del self.out_atom_ends[0]

    @program_end.action(value=lambda self: self.out_program_ends[0], when=lambda self: len(self.out_program_ends) > 0,
                        within=BEFORE_NEXT_TICK)
    def sent_program_end(self):
        del self.out_program_ends[0]

    @fault.action(value=lambda self: self.out_faults[0], when=lambda self: len(self.out_faults) > 0,
                  within=BEFORE_NEXT_TICK)
    def sent_fault(self):
        del self.out_faults[0]

    def _until_next_tick(self) -> float:
        now, period = esprit_now(), self._robot.period
        self._delay = (math.floor(now / period + GRID_SLACK) + 1) * period - now
        return self._delay

    def _tick(self, now: float) -> None:
        period = self._robot.period
        index = math.floor(now / period + GRID_SLACK)
        steps = 1 if self.tick_index is None else max(1, index - self.tick_index)
        self.tick_index, self._now = index, now
        self._apply_incoming()
        if self.command is None:
            if self.position is None:
                if self.running is not None and not self.waiting_reported:
                    self.waiting_reported = True
                    self._fault(self.running.program.id, "no joint_states yet: the program waits and the "
                                                         "motors get no setpoints until the joints are known")
                return
            self.command = self._held_within_limits(self.position)
        previous = self.command
        if self.running is not None:
            # a program that starts or resumes begins at its first step: the ticks a stall
            # skipped before it passed while it did not run, and crediting them would end it early
            self._run(self.running, 1 if self.began else steps)
            self.began = False
        dt = steps * period
        self.out_setpoint = self._setpoints_type(
            position=list(self.command), velocity_ff=[(c - p) / dt for c, p in zip(self.command, previous)],
            torque_ff=[0.0] * len(self.command))

    def _held_within_limits(self, position: list[float]) -> list[float]:
        """The first command: hold where the joints are, but never outside their limits (a joint
        measured beyond one is held at it, said once on `fault`: its setpoint jumps there)."""
        robot, command, outside = self._robot, [], []
        for name, p, lo, hi in zip(robot.joints, position, robot.lower, robot.upper):
            held = lo if p < lo else hi if p > hi else p
            if held != p:
                outside.append(f"{name} at {p:g} (limits [{lo:g}, {hi:g}])")
            command.append(held)
        if outside:
            self._fault(self.running.program.id if self.running is not None else "",
                        f"joints measured outside their limits: {', '.join(outside)}; held at the limit")
        return command

    @property
    def _setpoints_type(self):
        return type(self).setpoints.type

    def _run(self, run: ProgramRun, steps: int) -> None:
        """Interrupts first (an atom whose interrupt holds ends before it moves; the next one
        starts at this tick), then one step of the atom left standing, then its duration."""
        for _ in range(run.atom_count() + 1):
            try:
                if run.current is None:
                    self._start_atom(run)
                hit = self._interrupted(run)
            except MissingInput as missing:
                return self._hold(run, missing)
            except ProgramFault as fault:
                return self._fail(run, str(fault))
            except Exception as exc:  # noqa: BLE001 - what a program's numbers make fail is its fault
                return self._fail(run, _unforeseen(exc, run))
            if hit is None:
                break
            level, condition = hit
            self._atom_ended(run, "INTERRUPTED", level, condition)
            if level == "PLAN":
                return self._program_ended(run, "INTERRUPTED", level, condition)
            position = (run.behaviour, run.atom)
            more = run.next_behaviour() if level == "BEHAVIOUR" else run.next_atom()
            if not more:
                return self._program_ended(run, "DONE", "NONE", "", position)
        try:
            self._step(run, steps)
        except MissingInput as missing:
            return self._hold(run, missing)
        except ProgramFault as fault:
            return self._fail(run, str(fault))
        except Exception as exc:  # noqa: BLE001 - e.g. a sine of frequency 1e308: math domain error
            return self._fail(run, _unforeseen(exc, run))
        run.holding = None
        current = run.current
        atom = current.atom
        if atom.ticks is not None and current.ticks >= atom.ticks:
            if current.short is not None:
                # the atom ends at T, as the paper's atoms do, but the requester should know the
                # arm is not where the profile said: the velocity limit kept it behind
                gap, j = current.short
                robot = self._robot
                self._fault(run.program.id, f"behaviours[{atom.behaviour}].atoms[{atom.index}] ended at T = "
                                            f"{atom.T:g} s with joint {robot.joints[j]} {gap:.3g} short of its "
                                            f"reference: its max_velocity ({robot.max_velocity[j]:g}/s) kept it behind")
            self._atom_ended(run, "DONE", "NONE", "")
            position = (run.behaviour, run.atom)
            if not run.next_atom():
                self._program_ended(run, "DONE", "NONE", "", position)

    def _start_atom(self, run: ProgramRun) -> None:
        atom, robot = run.spec, self._robot
        where = f"behaviours[{atom.behaviour}].atoms[{atom.index}]"
        goal = None
        if atom.kind in ("ramp", "minimum_jerk"):
            if atom.pose is not None:
                try:
                    goal = self._kinematics.solve(atom.pose, self.command, robot.lower, robot.upper)
                except KinematicsError as exc:
                    raise ProgramFault(f"{where}.u.pose: {exc}") from None
            else:
                goal = [atom.goal.get(j, c) for j, c in enumerate(self.command)]
            for name, value, lo, hi in zip(robot.joints, goal, robot.lower, robot.upper):
                if not lo <= value <= hi:
                    raise ProgramFault(f"{where}.u: the goal of joint {name} ({value:.6g}) is outside its "
                                       f"limits [{lo:g}, {hi:g}]")
        run.current = AtomRun(atom, self.command, goal)

    def _interrupted(self, run: ProgramRun):
        """(level, condition) of the outermost interrupt that holds, or None. MissingInput for
        one that cannot be read, except in a wait: a wait moves nothing, and its T is the longest
        its author lets it wait, so an interrupt it cannot read is one that does not hold, and
        its clock runs on to T (a bad day's camera cut froze a pick's wait for vision's `near`
        until the scheduler's epoch ran out)."""
        compiled, atom = run.compiled, run.spec
        where = f"behaviours[{atom.behaviour}]"
        wait = _is_wait(run.current)
        for level, condition, place in (("PLAN", compiled.xi, "xi"),
                                        ("BEHAVIOUR", compiled.behaviour_xi[run.behaviour], f"{where}.xi"),
                                        ("ATOM", atom.xi, f"{where}.atoms[{atom.index}].xi")):
            if condition is None:
                continue
            try:
                if self._evaluate(condition, place):
                    return level, condition.text
            except MissingInput as missing:
                if not wait:
                    raise
                self._wait_unread(run, missing)
        return None

    def _evaluate(self, expression: CompiledExpression, where: str):
        for name in expression.reads:
            self._require(name)
        try:
            return expression.fn(self._inputs)
        except Exception as exc:  # noqa: BLE001 - a fault of the program, not of the node
            raise ProgramFault(f"{where}: {expression.text!r} failed: {type(exc).__name__}: {exc}") from None

    def _require(self, name: str) -> None:
        """The input `name` has a value that is valid and fresh, or MissingInput."""
        if name == POSITION:
            known, valid, since = self.position is not None, True, self.position_time
            source = "joint_states"
        else:
            k = self._layout.names.index(name)
            known, valid, since = self.sensor_time[k] > -math.inf, self.sensor_valid[k], self.sensor_time[k]
            source = f"sensor[{k}] ({name})"
        if not known:
            raise MissingInput(name, f"no value from {source} yet", "unknown")
        if not valid:
            raise MissingInput(name, f"{source} says its value is not valid", "invalid")
        age = self._now - since
        if age > self.sensor_timeout:
            raise MissingInput(name, f"the last value from {source} is {age:.3g} s old "
                                     f"(sensor_timeout {self.sensor_timeout:g} s)", "stale")

    def _step(self, run: ProgramRun, steps: int) -> None:
        current, robot = run.current, self._robot
        atom = current.atom
        dt = steps * robot.period
        where = f"behaviours[{atom.behaviour}].atoms[{atom.index}]"
        rates = None
        if atom.gains:  # read every input before time moves: a missing one holds the atom still
            rates = [0.0] * robot.size
            for g, (joint, expression, gain) in enumerate(atom.gains):
                value = self._evaluate(expression, f"{where}.k[{g}].sensor")
                rates[joint] += gain * value
        current.ticks += steps
        increments = None
        if rates is not None:
            increments = [r * dt for r in rates]
            current.feedback = [e + d for e, d in zip(current.feedback, increments)]
        reference = [u + e for u, e in zip(current.open_loop(current.ticks * robot.period), current.feedback)]
        command = []
        short = 0.0  # the largest gap the velocity limit left between a joint and its reference
        for j, (r, c) in enumerate(zip(reference, self.command)):
            if not math.isfinite(r):
                raise ProgramFault(f"{where}: the reference of joint {robot.joints[j]} is not finite ({r})")
            lo, hi = robot.lower[j], robot.upper[j]
            if r < lo or r > hi:
                limited = lo if r < lo else hi
                if increments is not None:
                    increments[j] = self._unwind(current, j, increments[j], limited - r)
                r = limited
            most = robot.max_velocity[j] * dt
            step = r - c
            if step > most or step < -most:
                if abs(step) - most > short:
                    short, slowest = abs(step) - most, j
                clipped = most if step > most else -most
                if increments is not None:
                    self._unwind(current, j, increments[j], clipped - step)
                step = clipped
            command.append(c + step)
        self.command = command
        current.short = (short, slowest) if short > GOAL_SLACK else None

    @staticmethod
    def _unwind(current, j: int, increment: float, cut: float) -> float:
        """Anti-windup: a limit (a joint's position limit, `max_velocity`) cut the reference by
        `cut`; the feedback integral gives back this step's increment where it pushed that way,
        up to the cut, and no more: it neither grows against a limit (a first-order law would
        overshoot) nor absorbs what the open-loop motion lost at it (a clipped sine would leave
        a lasting offset). Returns the increment left."""
        if increment * cut >= 0:  # it did not push toward the limit
            return increment
        back = -increment if abs(increment) <= abs(cut) else cut
        current.feedback[j] += back
        return increment + back

    # ------------------------------------------------------------------ commands
    def _command_arrived(self, program: Program) -> None:
        replaced = self.incoming
        if replaced is not None and replaced != program:
            saved = self.suspended.get(replaced.id)
            where = (saved.behaviour, saved.atom) if saved is not None and saved.program == replaced else (0, 0)
            self._report_program_end(replaced.id, "PREEMPTED", "NONE", "", where)
            self._refused.pop(replaced.id, None)
        self.incoming = program

    def _apply_incoming(self) -> None:
        """A new command preempts the running program at this tick; the preempted one is kept
        (up to max_suspended of them), so that the same program sent again resumes."""
        new = self.incoming
        if new is None:
            return
        self.incoming = None
        current = self.running
        if current is not None and current.program == new:
            return  # the program sent again while it runs: it goes on
        if current is not None:
            self._suspend(current)
        saved = self.suspended.pop(new.id, None)
        if saved is not None and saved.program == new:
            self.running = saved
            if saved.current is not None and self.command is not None:
                saved.current.reanchor(self.command, saved.current.ticks * self._robot.period)
            self.began = True
            return
        try:
            refused = self._refused.pop(new.id, None)
            if refused is not None:
                raise ProgramFault(refused)
            compiled = compile_program(new, self._robot, self._expressions)
        except Exception as fault:  # noqa: BLE001 - ProgramFault, or what its numbers made fail
            self.running = None
            why = str(fault) if isinstance(fault, ProgramFault) else _unforeseen(fault)
            self._fault(new.id, f"program {new.id!r} cannot run here: {why}; motors held")
            self._report_program_end(new.id, "FAULT", "NONE", "", (0, 0))
            return
        self.running = ProgramRun(compiled)
        self.began = True
        self.waiting_reported = False

    def _suspend(self, run: ProgramRun) -> None:
        self.running = None
        run.holding = None
        self._report_program_end(run.program.id, "PREEMPTED", "NONE", "", (run.behaviour, run.atom))
        if self.max_suspended == 0:
            return
        self.suspended.pop(run.program.id, None)
        self.suspended[run.program.id] = run
        while len(self.suspended) > self.max_suspended:
            del self.suspended[next(iter(self.suspended))]

    # ------------------------------------------------------------------ reports
    def _hold(self, run: ProgramRun, missing: MissingInput) -> None:
        """The motors stay where they are commanded; the atom's time stands still; said once per
        cause (a stale input's age grows every tick: it is said when it goes stale, not each tick)."""
        if run.holding != missing.key:
            run.holding = missing.key
            atom = run.spec
            self._fault(run.program.id, f"behaviours[{atom.behaviour}].atoms[{atom.index}] reads {missing}; "
                                        "motors held")

    def _wait_unread(self, run: ProgramRun, missing: MissingInput) -> None:
        """A wait whose interrupt cannot be read goes on to its T; said once per cause and atom."""
        key = (run.behaviour, run.atom, missing.key)
        if run.unread != key:
            run.unread = key
            atom = run.spec
            self._fault(run.program.id, f"behaviours[{atom.behaviour}].atoms[{atom.index}] reads {missing}; "
                                        f"a wait: it ends at its T ({atom.T:g} s) unless the value comes")

    def _fail(self, run: ProgramRun, message: str) -> None:
        self._fault(run.program.id, f"program {run.program.id!r} stopped: {message}; motors held")
        self._atom_ended(run, "FAULT", "NONE", "")
        self._program_ended(run, "FAULT", "NONE", "")

    def _atom_ended(self, run: ProgramRun, end: str, level: str, condition: str) -> None:
        elapsed = 0.0 if run.current is None else run.current.ticks * self._robot.period
        self.out_atom_ends.append(ATOM_END(
            program=run.program.id, behaviour=run.behaviour, atom=run.atom, end=end, level=level,
            condition=condition, tick=max(0, self.tick_index or 0), t=max(0.0, self._now), elapsed=elapsed))

    def _program_ended(self, run: ProgramRun, end: str, level: str, condition: str, where=None) -> None:
        self._report_program_end(run.program.id, end, level, condition, where or (run.behaviour, run.atom))
        if self.running is run:
            self.running = None

    def _report_program_end(self, program: str, end: str, level: str, condition: str, where) -> None:
        now = esprit_now()
        self.out_program_ends.append(PROGRAM_END(
            program=program, end=end, level=level, condition=condition, behaviour=where[0], atom=where[1],
            tick=max(0, self.tick_index or 0), t=max(0.0, now)))

    def _fault(self, program: str, message: str) -> None:
        self.out_faults.append(MDL_FAULT(program=program, message=message[:2000],
                                         tick=max(0, self.tick_index or 0), t=max(0.0, esprit_now())))


def _unforeseen(exc: Exception, run: ProgramRun | None = None) -> str:
    """A program fault that no check named: the error itself, at the atom that ran (an MDL
    program is input; whatever it makes fail ends that program with a fault, never the node)."""
    atom = getattr(run, "spec", None)
    where = f"behaviours[{atom.behaviour}].atoms[{atom.index}]: " if atom is not None else ""
    return f"{where}{type(exc).__name__}: {exc}"


@functools.cache
def interpreter_class(joints: int) -> type[MdlInterpreter]:
    """The interpreter class for `joints` joints: its setpoints and joint_states carry that many.
    (A channel's type belongs to the class; the subclass only redeclares those two channels, and
    the actions declared on them in MdlInterpreter apply to the redeclared ones by name.)"""
    if joints == MdlInterpreter.JOINTS:
        return MdlInterpreter
    if not isinstance(joints, int) or joints < 1:
        raise ValueError(f"an interpreter needs at least one joint, not {joints!r}")
    return type(f"MdlInterpreter{joints}", (MdlInterpreter,), {
        "__module__": __name__, "__doc__": f"The MDL interpreter for {joints} joints.", "JOINTS": joints,
        "setpoints": Output(joint_setpoints(joints)), "joint_states": Input(joint_states(joints))})


def mdl_interpreter(name: str | None = None, **params) -> MdlInterpreter:
    """An interpreter for as many joints as `joints` names (a node's `ref`:
    "nodes.mdl_interp:mdl_interpreter")."""
    joints = params.get("joints", XARM6_JOINTS)
    count = len(joints) if isinstance(joints, (list, tuple)) and joints else MdlInterpreter.JOINTS
    return interpreter_class(count)(name, **params)


__all__ = ["MdlInterpreter", "interpreter_class", "mdl_interpreter"]


def __getattr__(name: str):
    """`MdlInterpreter7` and the like, by name: a recording names the class of each node it
    holds, and `iotad check` / `iotad replay` rebuild the node by that name from this module."""
    prefix = "MdlInterpreter"
    if name.startswith(prefix) and name[len(prefix):].isdigit() and int(name[len(prefix):]) >= 1:
        return interpreter_class(int(name[len(prefix):]))
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _is_wait(current) -> bool:
    """Whether the atom under way is a wait: a hold with no feedback gains and an end T, which
    moves nothing whatever its interrupt reads."""
    atom = None if current is None else current.atom
    return atom is not None and atom.kind == "hold" and not atom.gains and atom.ticks is not None
