"""The IOTA kernel: value types, the model, the engine, clocks, policies, composition, dependency
tracking and the Python API. Imports nothing else of iotad (the bottom layer)."""
