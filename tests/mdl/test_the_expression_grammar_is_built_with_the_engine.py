"""Checking an MDL program's value parses its expressions, and the first parse imports the
ESPRIT front end and builds its grammar (about 0.1 s). An engine with an MDL program channel
does that as it is built (`Type.prepare`), so the cost lands at start-up, not in the first
firing that carries a program: in real time that firing is a node's do-block with a deadline.
Each case runs in a fresh interpreter, where nothing has built the grammar yet."""
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

PROBE = """
import sys
from iotad.kernel.api import Iota, Output
from iotad.kernel.clock import VirtualClock
from iotad.kernel.engine import Engine
from iotad.kernel.policy import Eager
from iotad.kernel.types import Float
{imports}

class Sender(Iota):
    out = Output({channel_type}, switching=0)

engine = Engine(Sender("sender"), VirtualClock(), Eager())
built = "iotad.esprit.expressions" in sys.modules and \\
    sys.modules["iotad.esprit.expressions"]._expression_parser.cache_info().currsize == 1
print("built" if built else "not built")
"""


def probe(channel_type: str, imports: str = "") -> str:
    code = PROBE.format(channel_type=channel_type, imports=imports)
    result = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    return result.stdout.strip()


def test_a_program_inside_a_request_struct_builds_the_grammar_with_the_engine():
    assert probe("MDL_PROGRAM_REQ", "from channels.mdl import MDL_PROGRAM_REQ") == "built"


def test_a_program_channel_builds_it_too():
    assert probe("MDL_PROGRAM", "from channels.mdl import MDL_PROGRAM") == "built"


def test_an_engine_without_programs_does_not_load_the_esprit_front_end():
    assert probe("Float(0, 1)") == "not built"
