"""`iotad new`: a working robot scaffolded from a few choices (joints, drives, behaviours, a
URDF world), as files a user owns and edits. Imports iotad.kernel only."""
