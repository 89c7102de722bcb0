"""The worker pool: work submitted runs on other threads, and a forked child gets a pool of its own (the parent's
threads do not exist in it; reusing its pool would wait forever)."""

import multiprocessing
import threading

from tracker.threads import worker_pool


def _thread_name() -> str:
    return threading.current_thread().name


def _pool_answers_in_child(queue) -> None:
    queue.put(worker_pool().submit(_thread_name).result(timeout=10))


def test_work_runs_on_the_worker_threads():
    assert worker_pool().submit(_thread_name).result(timeout=10).startswith("worker")


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
