"""The paper's message types (Figure 2): the MDL mode, the MDL request and the ack values."""
from __future__ import annotations

from iotad.kernel.types import Enum, Float, Int, Struct, Type

# struct mode { float w, k; }: w the control input (setpoint), k the feedback gain.
MODE = Struct("mode", w=Float, k=Float)

# struct mdlReq { struct mode control; float epoch, timeout; int priority; }
MDL_REQ = Struct("mdlReq", control=MODE, epoch=Float(0, None), timeout=Float(0, None), priority=Int)

# The scheduler's answer to a requester.
ACK = Enum("ack", "COMMIT", "ABORT", "REJECT")

REGISTRY: dict[str, Type] = {t.name: t for t in (MODE, MDL_REQ, ACK)}
