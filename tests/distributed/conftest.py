"""A Ray instance for the tests in this folder: a head on 127.0.0.1 with two worker CPUs, started in this
process once for the folder and shut down after its last test (``ray stop`` would end every Ray on the
machine; and the rest of the suite forks worker processes, which a live Ray in the parent does not like)."""

from __future__ import annotations

import logging

import pytest

from tests.conftest import run_lock


@pytest.fixture(scope="package")
def ray_cluster(tmp_path_factory):
    ray = pytest.importorskip("ray", reason="the Ray executor needs the 'ray' extra (pip install -e '.[ray]')")
    with run_lock(tmp_path_factory, "ray"):  # one local Ray at a time on the machine, as in one process
        started = not ray.is_initialized()
        if started:
            ray.init(
                address="local",
                num_cpus=2,
                _node_ip_address="127.0.0.1",
                include_dashboard=False,
                log_to_driver=False,
                logging_level=logging.WARNING,
            )
        assert ray.cluster_resources().get("CPU") == 2
        yield ray
        if started:
            ray.shutdown()
