"""Several hosts: the agents that run each host's part, the hub's fleet that orders them, the
files they run by content hash, each host's recording and the watch of its clock."""
