"""The BVH's measured thread choice: each option measured once, then the faster one, with the
other tried every EXPLORE_EVERY-th call so that a change in load is noticed."""

from classic_bake.kernels.geometry.thread_choice import EXPLORE_EVERY, ThreadChoice


def run(choice: ThreadChoice, calls: int, seconds_per_ray: dict[bool, float]) -> list[bool]:
    taken = []
    for _ in range(calls):
        threaded = choice.threaded()
        choice.record(threaded, 1000, 1000 * seconds_per_ray[threaded])
        taken.append(threaded)
    return taken


def test_measures_both_then_keeps_the_faster_and_explores_the_other():
    choice = ThreadChoice()
    taken = run(choice, 4 * EXPLORE_EVERY, {True: 1e-6, False: 2e-6})  # idle: threads win
    assert taken[:2] == [True, False]
    explored = [k for k in range(3, len(taken) + 1) if k % EXPLORE_EVERY == 0]  # call numbers
    assert [k for k in range(3, len(taken) + 1) if not taken[k - 1]] == explored


def test_follows_the_load_when_threads_start_losing():
    choice = ThreadChoice()
    run(choice, 3 * EXPLORE_EVERY, {True: 1e-6, False: 2e-6})
    # Another process takes a core: the threads now lose. Within a few explorations the choice
    # turns to one thread and stays there (trying threads once per period).
    taken = run(choice, 6 * EXPLORE_EVERY, {True: 3e-6, False: 2e-6})
    tail = taken[-3 * EXPLORE_EVERY:]
    assert tail.count(True) == 3


def test_ignores_empty_calls():
    choice = ThreadChoice()
    choice.record(True, 0, 1.0)
    choice.record(False, 10, 0.0)
    assert choice.threaded() is True  # still unmeasured
