"""The robots' virtual runs of a git revision against the working tree's, counted in CPU instructions.

    .venv/bin/python bench/instructions.py [--base main] [--world conveyor] [--seconds 10]

On a machine that others keep busy, seconds move by a third between two runs of one code, and
even CPU time moves with the load (shared caches, hyperthreads). The instructions a run executes
do not: `perf stat -e instructions:u` gives the same count within a fraction of a percent
whatever else the machine does, so a change of a few percent is seen in one run of each.
Instructions are not time (a cache miss costs no instruction), so the bigger a change the more
its time should be measured too (bench/worlds.py --cpu).

Where `perf` cannot count (a virtual machine without a PMU: "instructions:u <not supported>"),
`--counter valgrind` (the default then, when valgrind is installed) counts them with callgrind:
the system is built as `iotad run --virtual` builds it, with valgrind's instrumentation off, then
callgrind is switched on and counts the instructions inside `engine.run` alone (called through
`sys.call_tracing`, the C function callgrind's `--toggle-collect` watches), so start-up needs no
second run. Slower (about 10 CPU s of start-up and some 50x the run itself), as exact.
`--physics` counts, in one more run, the instructions inside PyBullet's API functions (its C
code: stepping, ray casts, the camera) and prints each run over them: the issue's "recorded over
physics-only", in instructions (a floor of the physics: the world's Python around PyBullet, which
bench/worlds.py's split counts as physics too, is not in it). With
`--record` the run is recorded as `iotad run -o` records it, by a writer process, whose own
instructions valgrind does not count: the engine's process alone (what bench/worlds.py's
"recorded (writer process)" times).

Each world runs as `iotad run SYSTEM --virtual --until S --no-record` in both trees (the base's
from `git archive`, run with this checkout's virtualenv), once for `--seconds` and once for a
thousandth of a second; the difference is the run itself, without start-up (imports, PyBullet's
worlds, ESPRIT's parsers). Figures: millions of instructions per virtual second, and the tree
over the base.
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# (Figure 2 is left out: its run is so small that start-up's own variation, a few million
# instructions, is most of its count)
WORLDS = {"conveyor": "examples/conveyor.toml", "buggy": "examples/buggy.toml"}
START_ONLY = 0.001  # s of virtual time: the run that counts start-up alone


def perf_available() -> str | None:
    """None if `perf stat` counts user-space instructions here; else why not."""
    if shutil.which("perf") is None:
        return "perf is not installed (Debian: apt-get install linux-perf)"
    probe = subprocess.run(["perf", "stat", "-x,", "-e", "instructions:u", "true"], capture_output=True, text=True)
    if probe.returncode != 0 or "not supported" in probe.stderr or "<not counted>" in probe.stderr:
        return f"perf cannot count instructions on this machine: {probe.stderr.strip()[:200]}"
    return None


COUNTER = "perf"  # --counter: perf stat, or valgrind's callgrind where perf cannot count
RECORD = False  # --record: each run recorded (`-o`, written by a second process, counted too)


def instructions(tree: Path, system: str, seconds: float) -> int:
    """User-space instructions of `iotad run SYSTEM --virtual --until seconds --no-record` in `tree`
    (with `--record`: `-o FILE --force` instead; perf counts the writer process too)."""
    recording = ["-o", str(Path(tempfile.gettempdir()) / f"iotad-instructions-{os.getpid()}.mcap"), "--force"]
    command = ["perf", "stat", "-x,", "-e", "instructions:u", sys.executable, "-m", "iotad", "run", system,
               "--virtual", "--until", repr(seconds), *(recording if RECORD else ["--no-record"])]
    # `python -m iotad` from the tree's root imports the tree's iotad, whatever the venv installed;
    # string hashes fixed, so that sets and dicts of names take the same steps in every run
    done = subprocess.run(command, cwd=tree, capture_output=True, text=True,
                          env=dict(os.environ, PYTHONHASHSEED="0"))
    if done.returncode != 0:
        raise SystemExit(f"bench/instructions.py: {' '.join(command[5:])} failed in {tree}:\n{done.stderr[-2000:]}")
    for line in done.stderr.splitlines():
        fields = line.split(",")
        if len(fields) > 2 and fields[2].startswith("instructions"):
            return int(fields[0])
    raise SystemExit(f"bench/instructions.py: perf printed no instruction count:\n{done.stderr[-1000:]}")


def valgrind_available() -> str | None:
    """None if valgrind's callgrind can count here; else why not."""
    if shutil.which("valgrind") is None or shutil.which("callgrind_control") is None:
        return "valgrind is not installed (Debian: apt-get install valgrind)"
    return None


# The C functions of PyBullet's Python API (pybullet_stepSimulation, pybullet_getCameraImage...):
# what callgrind counts for --physics, PyBullet's own work (the world's Python around it is not)
PHYSICS_FUNCTIONS = "pybullet_*"


def valgrind_instructions(tree: Path, system: str, seconds: float, inside: str = "sys_call_tracing") -> int:
    """Instructions of `engine.run` alone of `seconds` of `system` in `tree`, counted by callgrind
    (`inner_run` below, run in `tree` with this file); `inside=PHYSICS_FUNCTIONS`: those inside
    PyBullet's API functions during the run."""
    out = Path(tempfile.gettempdir()) / f"iotad-instructions-{os.getpid()}.callgrind"
    command = ["valgrind", "--tool=callgrind", "--instr-atstart=no", "--collect-atstart=no",
               f"--toggle-collect={inside}", f"--callgrind-out-file={out}",
               sys.executable, str(Path(__file__).resolve()), "--inner", system, repr(seconds)]
    if RECORD:
        command.append("--inner-record")
    try:
        done = subprocess.run(command, cwd=tree, capture_output=True, text=True,
                              env=dict(os.environ, PYTHONHASHSEED="0", PYTHONPATH=str(tree)))
    finally:
        out.unlink(missing_ok=True)
    if done.returncode != 0:
        raise SystemExit(f"bench/instructions.py: valgrind of {system} failed in {tree}:\n{done.stderr[-2000:]}")
    for line in done.stderr.splitlines():
        if "Collected :" in line:
            return int(line.split(":")[-1].strip().replace(",", ""))
    raise SystemExit(f"bench/instructions.py: callgrind printed no count:\n{done.stderr[-1000:]}")


def inner_run(system_file: str, seconds: float, record: bool) -> None:
    """Under callgrind, in a tree: build the system as `iotad run --virtual` does, switch
    callgrind's instrumentation on, and run the engine through `sys.call_tracing` (what callgrind
    counts). With `record`, as `iotad run -o` records: a writer process, the engine's side counted."""
    import gc
    here = Path(__file__).resolve().parent  # bench/ off the path: the tree's packages, not its scripts
    sys.path[:] = [os.getcwd()] + [p for p in sys.path if Path(p or ".").resolve() != here]
    from iotad.kernel.clock import VirtualClock
    from iotad.kernel.engine import Engine
    from iotad.kernel.policy import Eager
    from iotad.launcher.system.in_process import compose
    from iotad.launcher.system.system_file import load_system
    system = load_system(Path(system_file))
    root = compose(system)
    sinks, writer = [], None
    if record:
        from iotad.recording.engine_sink import recording_header
        from iotad.recording.writer_process import RecordingProcess
        writer = RecordingProcess()
        writer.open(Path(tempfile.gettempdir()) / f"iotad-instructions-{os.getpid()}.mcap")
        writer.begin(recording_header(root, system.name, time_unit=system.time_unit))
        sinks.append(writer)
    engine = Engine(root, VirtualClock(), Eager(), record=False, sinks=sinks)
    gc.freeze()  # as `iotad run --virtual` does
    # callgrind watches for a command file while the process runs: instrumentation is on once
    # callgrind_control has returned (it waits for the answer)
    subprocess.run(["callgrind_control", "--instr=on", str(os.getpid())], stdout=subprocess.DEVNULL, check=True)
    sys.call_tracing(engine.run, (seconds,))
    if writer is not None:
        sys.call_tracing(writer.finish, ())  # the last batch's packing and sending, counted
        Path(writer.output).unlink(missing_ok=True)
    # off before the worlds close (PyBullet's disconnect is no part of the run)
    subprocess.run(["callgrind_control", "--instr=off", str(os.getpid())], stdout=subprocess.DEVNULL, check=True)


def run_instructions(tree: Path, system: str, seconds: float) -> int:
    """Instructions of the run alone: `seconds` of virtual time less a run that only starts.
    A first run, not counted, compiles the tree's bytecode (`__pycache__`: a fresh `git archive`
    has none, and compiling it is some 100 million instructions) and fills the parser cache."""
    if COUNTER == "valgrind":
        return valgrind_instructions(tree, system, seconds)
    instructions(tree, system, START_ONLY)
    return instructions(tree, system, seconds) - instructions(tree, system, START_ONLY)


def extract(revision: str, into: Path) -> Path:
    """The tree of `revision`, as `git archive` gives it."""
    archive = into / "base.tar"
    with open(archive, "wb") as out:
        made = subprocess.run(["git", "-C", str(ROOT), "archive", revision], stdout=out, stderr=subprocess.PIPE,
                              text=True)
    if made.returncode != 0:
        raise SystemExit(f"bench/instructions.py: no revision {revision!r}: {made.stderr.strip()}")
    tree = into / "base"
    with tarfile.open(archive) as tar:
        tar.extractall(tree, filter="data")
    return tree


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--base", default="main", help="the git revision to compare with (default: main)")
    parser.add_argument("--world", action="append", choices=sorted(WORLDS),
                        help="a world to run (repeatable; default: conveyor and buggy)")
    parser.add_argument("--seconds", type=float, default=10.0, help="virtual seconds per run (default: 10)")
    parser.add_argument("--record", action="store_true",
                        help="record each run as iotad run -o does (perf counts its writer process too; valgrind the "
                             "engine's process alone), not --no-record")
    parser.add_argument("--physics", action="store_true",
                        help="valgrind only: also count PyBullet's own instructions (its API's C functions) "
                             "and print each run over them (the issue's recorded over physics-only)")
    parser.add_argument("--counter", choices=("auto", "perf", "valgrind"), default="auto",
                        help="what counts: perf stat, or valgrind's callgrind (auto: perf where it can count)")
    parser.add_argument("--inner", nargs=2, metavar=("SYSTEM", "SECONDS"), help=argparse.SUPPRESS)
    parser.add_argument("--inner-record", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.inner:  # under callgrind, in a tree (valgrind_instructions)
        inner_run(args.inner[0], float(args.inner[1]), args.inner_record)
        return 0
    global RECORD, COUNTER
    RECORD = args.record
    if not args.seconds > START_ONLY:
        parser.error(f"--seconds must be more than {START_ONLY}")
    why = perf_available() if args.counter != "valgrind" else "--counter valgrind"
    if why and args.counter == "perf":
        print(f"bench/instructions.py: {why}", file=sys.stderr)
        return 2
    if why:
        why_not = valgrind_available()
        if why_not:
            print(f"bench/instructions.py: {why}; and {why_not}", file=sys.stderr)
            return 2
        COUNTER = "valgrind"
    worlds = args.world or ["conveyor", "buggy"]
    with tempfile.TemporaryDirectory(prefix="iotad-bench-") as folder:
        base = extract(args.base, Path(folder))
        how = ("callgrind, engine.run alone" + (", the engine's process (a writer process records)" if RECORD else "")
               if COUNTER == "valgrind" else
               f"perf, start-up taken off, `iotad run --virtual {'-o FILE' if RECORD else '--no-record'}`")
        print(f"user-space instructions of {args.seconds:g} s of virtual time ({how}); base {args.base}, tree {ROOT}")
        physics = args.physics and COUNTER == "valgrind"
        print(f"  {'world':10} {'base M/s':>10} {'tree M/s':>10} {'tree/base':>10}"
              + (f" {'PyBullet M/s':>13} {'base/PyBullet':>14} {'tree/PyBullet':>14}" if physics else ""))
        for world in worlds:
            counts = {name: run_instructions(tree, WORLDS[world], args.seconds) / args.seconds / 1e6
                      for name, tree in (("base", base), ("tree", ROOT))}
            line = f"  {world:10} {counts['base']:10.1f} {counts['tree']:10.1f} {counts['tree'] / counts['base']:9.3f}x"
            if physics:  # the same world steps the same way in both trees: counted in the tree
                pybullet = valgrind_instructions(ROOT, WORLDS[world], args.seconds, PHYSICS_FUNCTIONS) / args.seconds / 1e6
                line += (f" {pybullet:13.1f} {counts['base'] / pybullet:13.2f}x {counts['tree'] / pybullet:13.2f}x"
                         if pybullet else f" {'0':>13} {'-':>14} {'-':>14}")
            print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
