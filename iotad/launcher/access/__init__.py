"""Access control: who may publish and subscribe what, derived from the checked system, on one
host and across hosts (the hub's policy, each host's router of its nodes)."""
