"""The launcher behind `iotad run`, in packages by job, each importing only those before it:
`system` (the declaration and the checked model), `access` (who may publish what), `hosts`
(agents, the hub's fleet, code by hash) and `run` (the run of one host); `options`, `processes`
and `fleet_wire` sit beside them. Imports the layers below it only (kernel, esprit, can, ros2,
machine, node_host)."""
