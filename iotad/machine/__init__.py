"""A machine of a system spread over hosts: its certificates (the system's own authority, one
certificate per host), its agent's secret, and its clock measured against the hub's. Not the node
host (iotad.node_host), which is the process that runs one IOTA on whichever machine."""
