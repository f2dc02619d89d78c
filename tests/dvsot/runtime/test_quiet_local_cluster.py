"""A local:N cluster leaves Dask's own log lines off for the rest of the process: its event loop outlives it, and a
comm that closes as a run stops would otherwise print a traceback under the run's one-line message."""

import logging

from dvsot.runtime.dask_tasks import Cluster


def test_a_comm_closing_after_the_cluster_prints_nothing(capfd):
    with Cluster("local:1"):
        pass
    capfd.readouterr()
    try:
        raise ConnectionError("closed")
    except ConnectionError:
        logging.getLogger("distributed.batched").info("Batched Comm Closed", exc_info=True)
    logging.getLogger("distributed.core").warning("connection lost")
    out, err = capfd.readouterr()
    assert (out, err) == ("", "")
    assert logging.getLogger("distributed").getEffectiveLevel() == logging.CRITICAL
