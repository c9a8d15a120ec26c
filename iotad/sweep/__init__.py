"""Sweeps: many virtual runs of one system over a grid (or random points) of node parameters and
seeds, in a local process pool or as Ray tasks, one row of metrics per run (docs/sweeps.md).
`iotad sweep` parses its command line and calls these; errors are `SweepError`, one line."""


class SweepError(Exception):
    """A sweep that cannot be made as asked (its file, a --set, its folder, Ray), said in one line."""
