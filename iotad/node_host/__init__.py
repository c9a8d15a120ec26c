"""The node host: one IOTA as one process on zenoh (wire format, transport, channel table, host clock).
Imports iotad.kernel, iotad.esprit and iotad.can only. `python -m iotad.node_host CONFIG.json` runs a node."""
