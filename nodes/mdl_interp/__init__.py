"""The MDL interpreter: motion programs to per-joint commands (not written yet)."""
