"""The docs cannot rot: every `iotad ...` command in the README tour and in docs/*.md code blocks
parses with today's command line, the quick ones (spec check/show/run, run --check,
demo --virtual) run and succeed, and the system-file reference's full example checks clean."""
import re
import shlex
from pathlib import Path

import pytest

from iotad.cli import build_parser, main

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"
DOCS = sorted((ROOT / "docs").glob("*.md"))


def code_blocks(text: str, language: str = "sh") -> list[str]:
    return re.findall(rf"```{language}\n(.*?)```", text, flags=re.S)


def commands(text: str) -> list[list[str]]:
    """`iotad ...` lines of the sh code blocks, as argv lists (without 'iotad'); comments dropped."""
    found = []
    for block in code_blocks(text):
        for line in block.splitlines():
            line = line.split("  #", 1)[0].strip()
            if line.startswith("iotad "):
                found.append(shlex.split(line)[1:])
    return found


def tour() -> str:
    text = README.read_text()
    return text[text.index("## Tour"):text.index("\n## ", text.index("## Tour") + 1)]


TOUR = commands(tour())
QUICK = [argv for argv in TOUR
         if argv[:1] == ["spec"] or argv[:2] == ["run", "--check"] or argv[:2] == ["demo", "--virtual"]]


def test_tour_covers_the_workflow():
    used = {argv[0] for argv in TOUR}
    assert {"spec", "demo", "run", "ls", "echo", "hz", "record", "info", "replay", "check", "plot"} <= used
    assert README.read_text().index("make demo") < README.read_text().index("make test") < README.read_text().index("## Tour")


@pytest.mark.parametrize("argv", [a for doc in [README, *DOCS] for a in commands(doc.read_text())],
                         ids=lambda argv: " ".join(argv)[:50])
def test_documented_commands_parse(argv):
    build_parser().parse_args(argv)  # a usage error exits


@pytest.mark.parametrize("argv", QUICK, ids=lambda argv: " ".join(argv)[:50])
def test_quick_tour_commands_run(argv, capsys, monkeypatch):
    monkeypatch.chdir(ROOT)
    assert main(argv) == 0, capsys.readouterr().err
    out = capsys.readouterr().out
    if argv[:2] == ["spec", "run"]:
        import json
        events = [json.loads(line) for line in out.splitlines()]
        acks = {e["value"] for e in events if e["action"] == "ack"}
        assert acks == {"COMMIT", "ABORT", "REJECT"}  # what the tour promises the script shows
        assert all(list(e) == ["t", "iota", "action", "index", "kind", "value"] for e in events)


def test_tour_files_exist():
    for argv in TOUR:
        for arg in argv:
            if re.match(r"^(examples|nodes)/", arg):
                assert (ROOT / arg).exists(), arg


def test_system_file_reference_example_checks(tmp_path, capsys):
    """The full example of docs/system-file.md is a valid system file (paths made absolute)."""
    text = (ROOT / "docs" / "system-file.md").read_text()
    examples = [b for b in code_blocks(text, "toml") if "[system]" in b and "[[node]]" in b]
    assert examples
    for number, block in enumerate(examples):
        block = block.replace('"../nodes/', f'"{ROOT}/nodes/').replace('"requesters.py', f'"{ROOT}/examples/requesters.py')
        path = tmp_path / f"example{number}.toml"
        path.write_text(block)
        assert main(["run", "--check", str(path)]) == 0, capsys.readouterr().err


def test_system_file_reference_names_every_key():
    """Every key the system file parser accepts is documented."""
    from iotad.launcher.system import declaration as system
    text = (ROOT / "docs" / "system-file.md").read_text()
    keys = system._SYSTEM_KEYS | system._NODE_KEYS | system._TOP_KEYS | system._CAN_KEYS | {"listen", "connect", "from", "to"}
    missing = sorted(k for k in keys if f"`{k}`" not in text)
    assert not missing, missing


def test_esprit_inclusion_example_checks_and_runs():
    """docs/esprit.md's composite example, with the counter and doubler it says it includes."""
    from iotad.esprit import check_text, load_text
    from iotad.kernel.input_script import run_script

    text = (ROOT / "docs" / "esprit.md").read_text()
    example = re.search(r"```\n(iota clocked.*?)```", text, flags=re.S).group(1)
    components = """
    iota counter: tick()/0 -> count(int)/0 {
      states int n = 0, c = 0;
      actions tick() do n = n + 1;  count(n) when n > c do c = n; }
    iota doubler(float GAIN = 2.0): inp(int)/0 -> out(float)/0 {
      states float v = 0.0; bool has = false;
      actions inp(x) do { v = x * GAIN; has = true; }  out(v) when has do has = false; }
    """
    spec = components + example
    assert check_text(spec) == ([], [])
    trace = run_script(load_text(spec).iotas["clocked"](), [], 5.0).trace
    assert [(e["t"], e["value"]) for e in trace if e["kind"] == "output" and e["action"] == "out"] == \
        [(1.0, 2.0), (2.0, 4.0), (3.0, 6.0)]
