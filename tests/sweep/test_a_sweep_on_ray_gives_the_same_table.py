"""The grid as Ray tasks on a local Ray cluster of 2 CPUs gives the local pool's table, and each
run's recording and log come back into the sweep's folder."""
import pytest

from sweep_iotas import sweep


def test_ray_tasks_give_the_local_table(system, first_table, tmp_path):
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        assert sweep(system, tmp_path / "ray", "--ray") == 0
    finally:
        ray.shutdown()
    assert (tmp_path / "ray" / "results.csv").read_text() == first_table
    assert sorted(p.name for p in (tmp_path / "ray" / "runs").glob("*.mcap")) == \
        [f"run-{k:04d}.mcap" for k in range(8)]
    assert "summary of ticker" in (tmp_path / "ray" / "runs" / "run-0000.log").read_text()
