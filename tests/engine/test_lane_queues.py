"""How the sampled-trajectory lanes cut a run into queues (engine/sampling.py): each forcing period's
points into whole queues that the threads take side by side, every point in exactly one queue, the
lanes of a queue about half its points (a lane without a point is stepped all the same)."""
import numpy as np
import pytest

from mechsweep.engine import sampling


@pytest.mark.parametrize("most,points,queues,expected", [
    (32, 20, 1, (8, 1)),  # 20 points: 8 lanes (three rounds) rather than 32 mostly idle ones
    (32, 40, 1, (16, 1)),
    (32, 64, 2, (16, 2)),  # 32 points per queue: 16 lanes
    (32, 1000, 2, (32, 2)),
    (16, 1000, 2, (16, 2)),  # no more lanes than the memory bound allows
    (32, 12, 4, (8, 1)),  # at least 8 points a queue
    (8, 3, 2, (8, 1)),
])
def test_a_periods_queues_and_lanes(most, points, queues, expected):
    assert sampling.group_lanes(most, points, queues) == expected


def _points_by_queue(tasks):
    return [idx[first::step] for idx, _, _, first, step in tasks]


def test_many_small_periods_are_one_queue_each_and_every_point_is_taken_once():
    """A sweep of the forcing frequency: 200 periods of 20 points. On 2 threads each period is one
    queue (the threads take different periods side by side), not two half-empty ones."""
    groups = [(np.arange(20 * g, 20 * g + 20), np.full(5, float(g))) for g in range(200)]
    tasks = sampling._lane_tasks(groups, 32, 2)
    assert len(tasks) == 200 and all(t[2] == 8 and t[4] == 1 for t in tasks)
    taken = np.concatenate(_points_by_queue(tasks))
    assert np.array_equal(np.sort(taken), np.arange(4000))


def test_a_large_period_is_shared_by_the_threads_and_the_largest_queues_go_first():
    groups = [(np.arange(0, 30), np.zeros(3)), (np.arange(30, 1030), np.ones(3)), (np.arange(1030, 1050), np.ones(3))]
    tasks = sampling._lane_tasks(groups, 32, 4)
    sizes = [t[0].size // t[4] for t in tasks]
    assert sizes == sorted(sizes, reverse=True)
    assert [t[4] for t in tasks if t[0].size == 1000] == [4] * 4  # the large period: every thread
    assert np.array_equal(np.sort(np.concatenate(_points_by_queue(tasks))), np.arange(1050))
    for idx, te, _, first, step in tasks:  # a queue integrates the points of its own period
        assert te[0] == (0.0 if idx[0] < 30 else 1.0)


def test_a_thread_that_stops_stops_the_others_taking_queues(monkeypatch):
    """A queue that raises (Ctrl-C reaching a thread between its kernel calls) ends the launch once the
    queues in flight return: the other thread takes no new one."""
    import threading
    import time
    from types import SimpleNamespace

    calls, lock, second, raised = [], threading.Lock(), threading.Event(), threading.Event()

    def queue(width, idx, first, step, *rest):
        with lock:
            calls.append(idx[0])
            first_call = len(calls) == 1
        if first_call:  # raises once the other thread is inside its first queue
            second.wait(5)
            try:
                raise KeyboardInterrupt
            finally:
                raised.set()
        second.set()
        raised.wait(5)
        time.sleep(0.2)  # the raising thread has marked the launch stopped by now

    model = SimpleNamespace(states=("x",), params=(), settings=(), internal=())
    periods = np.repeat(np.arange(1.0, 7.0), 16)  # six periods of 16 points: six queues

    def setup(P, S, rtol, PF, Z0, TT, code, mstat):
        TT[:] = periods

    mod = SimpleNamespace(setup=setup, queue=queue, kernel=None)
    monkeypatch.setattr(sampling._jit, "num_threads", lambda: 2)
    z = np.zeros(periods.size)
    with pytest.raises(KeyboardInterrupt):
        sampling._run_lanes(mod, model, np.zeros((periods.size, 1)), (), np.arange(3.0), None, None, None,
                            SimpleNamespace(rtol=1e-8, atol=1e-10, max_steps=10), z, z, z, z,
                            np.zeros(periods.size, dtype=np.int64), z, z, z)
    assert len(calls) == 2  # the queue that raised and the one in flight beside it; four never taken
