"""The launcher: system files, process supervision and the status view behind `iotad run`.
Imports iotad.kernel, iotad.esprit, iotad.node_host and iotad.can only."""
