"""Whether a call releases the GIL, observed by a count, not by a clock (tests/test_threads.py,
tests/test_encode.py)."""
from __future__ import annotations

import sys
import threading
import time
from typing import Callable


def calls_that_let_python_run(call: Callable[[], object], wanted: int = 3, tries: int = 50) -> int:
    """How many of up to ``tries`` calls of ``call`` another Python thread counted during (stops
    at ``wanted``). With a switch interval far longer than a call, the interpreter never takes
    the GIL from this thread during it, so the counting thread's count can move only if the call
    itself released the GIL. Repeated: on a loaded machine the counter may not be scheduled
    during a given call."""
    count = 0
    counting, stop = threading.Event(), threading.Event()

    def counter() -> None:
        nonlocal count
        while not stop.is_set():
            count += 1
            counting.set()
            time.sleep(0)  # gives the GIL back at once, so the call's end does not wait for it

    interval = sys.getswitchinterval()
    thread = threading.Thread(target=counter)
    thread.start()
    progressed = 0
    try:
        counting.wait()
        sys.setswitchinterval(30.0)
        for _ in range(tries):
            before = count
            call()
            progressed += count > before
            if progressed >= wanted:
                break
    finally:
        sys.setswitchinterval(interval)
        stop.set()
        thread.join()
    return progressed
