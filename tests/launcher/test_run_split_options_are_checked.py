"""`iotad run --max-size/--max-duration` (a split recording): bad values and combinations that
make no sense are one-line errors with exit status 2, before anything starts."""
import pytest

from iotad.cli import main
from launcher_helpers import ROOT

FIGURE2 = str(ROOT / "examples" / "figure2.toml")


@pytest.mark.parametrize("args, says", [
    (["--no-record", "--max-size", "1M"], "not with --no-record"),
    (["--max-size", "0"], "must be a positive size"),
    (["--max-size", "lots"], "expected a size such as 100M"),
    (["--max-duration", "-1"], "--max-duration"),
    (["--virtual", "--until", "1", "--max-duration", "5"], "not a --virtual one"),
])
def test_bad_split_option_is_a_one_line_error(args, says, capsys):
    try:
        code = main(["run", FIGURE2, *args])
    except SystemExit as exc:
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2 and says in err, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
