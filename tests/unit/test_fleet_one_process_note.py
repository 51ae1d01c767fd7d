"""The note that one process would have been faster: said from what was measured."""

from types import SimpleNamespace

from loadbayes.fleet.run import one_process_note


def _engine(workers, startup, waited, cpu):
    return SimpleNamespace(
        workers=workers, startup_seconds=startup, map_seconds=waited, task_cpu_seconds=cpu
    )


def test_said_when_the_tasks_cost_less_cpu_than_the_cluster_took():
    # 24 buses on 2 workers, as measured: 1.2 s of task CPU, 1.8 s waited, 0.6 s to start
    note = one_process_note(_engine(2, 0.6, 1.8, 1.2))
    assert "one process (no --workers) would have been faster" in note
    assert "1.2 s of CPU" in note and "0.6 s to start" in note
    assert "while 1 worker took 1.8 s" in one_process_note(_engine(1, 0.6, 1.8, 1.2))


def test_silent_when_the_workers_paid_for_themselves_or_there_are_none():
    # 200 pooled buses: 33 s of task CPU in 19 s on 2 workers (one process took 29 s)
    assert one_process_note(_engine(2, 0.7, 18.5, 33.0)) == ""
    assert one_process_note(_engine(None, 0.0, 0.0, 0.0)) == ""  # in process
    assert one_process_note(_engine(2, 0.6, 0.0, 0.0)) == ""  # nothing ran on the cluster
