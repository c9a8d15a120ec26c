"""Message types carried on channels, shared by Python IOTAs, ESPRIT specs and the recorder."""
from .messages import ACK, MDL_REQ, MODE, REGISTRY

__all__ = ["ACK", "MDL_REQ", "MODE", "REGISTRY"]
