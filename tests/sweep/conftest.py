"""The sweep tests' shared grid: 2 x 2 parameters of the ticker system, 2 seeds, 5 s of
virtual time each, and its table, swept once (locally) for every test that compares with it."""
import pytest

from sweep_iotas import sweep, write_system


@pytest.fixture(scope="session")
def system(tmp_path_factory):
    return write_system(tmp_path_factory.mktemp("ticker"))


@pytest.fixture(scope="session")
def first_table(system, tmp_path_factory):
    out = tmp_path_factory.mktemp("first") / "sweep"
    assert sweep(system, out, "-j", "2") == 0
    return (out / "results.csv").read_text()
