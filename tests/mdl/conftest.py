"""Fixtures of the MDL interpreter tests (helpers: mdl_harness.py, importable from this folder)."""
import pytest

from mdl_harness import Run, arm


@pytest.fixture
def make_run():
    """`make_run(**interpreter_params)`: a Run over an interpreter and a perfect motor;
    `make_run(root)`: over a system of your own."""
    return lambda root=None, **params: Run(root if root is not None else arm(**params))
