"""Jobs shared between the caller and the worker threads: each done once, by whoever reaches it first, its result
or its exception handed to the caller; and a forked child gets workers of its own (the parent's threads do not
exist in it; reusing its pool would wait forever)."""

import multiprocessing
import threading
import time

import pytest

from tracker.threads import WORKERS, TwoEndedJobs, worker_pool


def _thread_name() -> str:
    return threading.current_thread().name


def _pool_answers_in_child(queue) -> None:
    queue.put(worker_pool().submit(_thread_name).result(timeout=10))


def test_every_job_is_done_once_and_its_result_handed_back():
    done, lock = [], threading.Lock()

    def job(index: int):
        time.sleep(0.001)  # long enough for the workers to take some
        with lock:
            done.append((index, _thread_name()))
        return index * index

    jobs = TwoEndedJobs([lambda index=index: job(index) for index in range(40)])
    assert jobs.results() == [index * index for index in range(40)]
    assert sorted(index for index, _ in done) == list(range(40))  # none twice
    by_worker = [index for index, name in done if name.startswith("worker")]
    assert by_worker and max(by_worker) == 39  # the workers start from the back


def test_a_failed_job_raises_when_its_result_is_asked_for():
    def fails():
        raise ValueError("no silhouette")

    jobs = TwoEndedJobs([lambda: 1, fails, lambda: 3])
    assert jobs.result(0) == 1
    with pytest.raises(ValueError, match="no silhouette"):
        jobs.result(1)
    assert jobs.result(2) == 3


def test_a_forked_child_makes_its_own_pool():
    worker_pool().submit(_thread_name).result(timeout=10)  # the parent's threads exist before the fork
    context = multiprocessing.get_context("fork")
    queue = context.Queue()
    child = context.Process(target=_pool_answers_in_child, args=(queue,))
    child.start()
    child.join(timeout=30)
    alive = child.is_alive()
    if alive:
        child.kill()
    assert not alive and child.exitcode == 0
    assert queue.get(timeout=1).startswith("worker")


def test_settled_jobs_not_taken_never_start_and_those_under_way_are_waited_for():
    release, lock = threading.Event(), threading.Lock()
    started, finished = [], []

    def job(index: int):
        with lock:
            started.append(index)
        release.wait(timeout=10)
        time.sleep(0.02)
        with lock:
            finished.append(index)
        raise ValueError("dropped with its result")

    jobs = TwoEndedJobs([lambda index=index: job(index) for index in range(20)])
    deadline = time.monotonic() + 10
    while not started and time.monotonic() < deadline:  # the workers take some (each blocks until released)
        time.sleep(0.001)
    threading.Timer(0.3, release.set).start()  # long after settle has kept the others from starting
    jobs.settle()
    with lock:
        assert sorted(finished) == sorted(started) and 1 <= len(started) <= WORKERS  # under way: waited for
    time.sleep(0.1)
    assert len(started) <= WORKERS  # the others never started
