"""Robot nodes: the motion scheduler, the MDL interpreter and the CAN motor node."""
