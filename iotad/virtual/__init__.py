"""Runs in one process in virtual time: a system file's IOTAs composed and run as fast as the
machine allows, recorded as a real-time run is (`run_virtual(system, VirtualOptions(...))`)."""
