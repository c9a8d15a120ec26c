"""The CAN-bus motor node: per-joint commands to CAN frames (not written yet)."""
