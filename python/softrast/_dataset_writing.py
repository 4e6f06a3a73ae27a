"""What both dataset stores (files and zarr) share: writer threads fed while views render, Ctrl-C
between views, a progress bar, resume's checks, and what ``write_dataset`` returns."""
from __future__ import annotations

import concurrent.futures
import contextlib
import os
import signal
import threading
from typing import Any, Iterable, Sequence

from .frame import _read_output


def _remove_stale_temporaries(directory: str, stems: Sequence[str]) -> None:
    """Removes the hidden temporary files a killed run left (imwrite's ``.{file}.{pid}-{id}.tmp*``
    and cameras.json's ``cameras.json.{pid}.tmp``) for this dataset's views: an interrupted
    write never replaced a file, so they hold nothing."""
    prefixes = tuple(f".{stem}_" for stem in stems)
    for name in os.listdir(directory):
        if (name.startswith(prefixes) and ".tmp" in name) or \
                (name.startswith("cameras.json.") and name.endswith(".tmp")):
            try:
                os.remove(os.path.join(directory, name))
            except FileNotFoundError:
                pass


def _intact(path: str, name: str, height: int, width: int) -> bool:
    """Whether ``path`` decodes to output ``name`` as save writes it, ``height`` x ``width``."""
    try:
        return _read_output(path, name).shape[:2] == (height, width)
    except (ValueError, OSError, MemoryError):
        return False


class WrittenViews(list):
    """What ``write_dataset`` returns: a list of each view's {output: path}, in camera order (the
    views skipped by ``resume`` included), that also says what this call did:

    rendered : the number of views rendered and written by this call.
    skipped : the number of views skipped because their files were all there (``resume``).
    seconds : the wall time spent rendering and writing the rendered views (0.0 if none), so a
        rate is ``rendered / seconds``: skipped views cost no rendering and are not counted.
    """

    def __init__(self, paths: Iterable[dict[str, str]] = (), rendered: int = 0, skipped: int = 0,
                 seconds: float = 0.0) -> None:
        super().__init__(paths)
        self.rendered = int(rendered)
        self.skipped = int(skipped)
        self.seconds = float(seconds)

    def __repr__(self) -> str:
        return (f"WrittenViews({list.__repr__(self)}, rendered={self.rendered}, "
                f"skipped={self.skipped}, seconds={self.seconds:.3f})")


def _progress_bar(total: int, skipped: int) -> Any:
    """write_dataset's tqdm bar, starting at the views resume skipped (named in it): tqdm's rate
    counts from `initial`, so only the views rendered make it."""
    from tqdm.auto import tqdm
    return tqdm(total=total, initial=skipped, unit="view", desc="write_dataset",
                postfix=f"skipped {skipped}" if skipped else None)


@contextlib.contextmanager
def _interrupt_between_views() -> Any:
    """Defers Ctrl-C (SIGINT) in a dataset writer to the next view: yields ``check()``, which
    raises KeyboardInterrupt once one arrived. Raised asynchronously, it could land inside
    concurrent.futures' own locks (pool.submit holds its semaphore's), and the pool's shutdown
    then waited forever for a writer blocked on that lock (seen under load: a `softrast batch`
    that hung after Ctrl-C). Only in the main thread, and only over Python's own handler; one
    that arrived after the last view still raises on the way out."""
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is not signal.default_int_handler):
        yield lambda: None
        return
    arrived: list[int] = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: arrived.append(signum))

    def check() -> None:
        if arrived:
            raise KeyboardInterrupt

    try:
        yield check
    finally:
        signal.signal(signal.SIGINT, previous)
    check()


def _write_frames(pool: concurrent.futures.Executor, frames: Iterable[Any], todo: Sequence[int],
                  write: Any, done: dict[int, Any], bar: Any, n_writers: int,
                  check: Any = lambda: None) -> None:
    """Hands each frame of ``frames`` (those of views ``todo``, in order) to the writers as
    ``write(frame, k)`` while the next views render, at most 2 frames a writer waiting (so memory
    stays bounded), and keeps each view's result in ``done[k]``, in order, ticking ``bar``.
    ``check()`` (_interrupt_between_views) runs between views."""
    pending: list[tuple[int, concurrent.futures.Future]] = []

    def drain(limit: int) -> None:
        while len(pending) > limit:
            k, fut = pending.pop(0)
            done[k] = fut.result()
            if bar is not None:
                bar.update(1)
            check()

    for k, frame in zip(todo, frames):
        check()
        pending.append((k, pool.submit(write, frame, k)))
        drain(2 * n_writers)
    drain(0)
