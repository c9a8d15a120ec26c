"""Recordings: the MCAP recorder, reading, replay, conformance checking, export and plots.
Imports iotad.kernel, iotad.esprit, iotad.node_host, iotad.can and iotad.launcher only."""
