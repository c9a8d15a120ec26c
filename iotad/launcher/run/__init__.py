"""The run of one host: the launcher of its nodes and recorder (supervision, status view,
recording names), and the real-time run of a system as the library does it (`run_system`)."""
