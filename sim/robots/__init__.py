"""Robot descriptions shipped with iotad, named by package from any folder:
`world_options = { urdf = "sim.robots:pan_tilt.urdf" }` (docs/simulation.md, "Your own robot")."""
