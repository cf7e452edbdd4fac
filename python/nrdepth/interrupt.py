"""Ctrl-C that is never lost, and never lost half-way. Python turns SIGINT
into a KeyboardInterrupt wherever the main thread happens to be, and some
libraries swallow it there: of 12 sent during ``import torch``, one was
caught inside the import, and the run went on to write its output. Inside :func:`sigint_remembered` the signal is also remembered, and
:func:`raise_if_interrupted`, called between the main job's stages and
before its output is renamed into place, raises it again. Once the output
is being renamed into place (:func:`committed`) the job is done: a later
SIGINT is only remembered, so an exit status of 130 always means that
nothing was written, and 0 that everything was."""

from __future__ import annotations

import signal
import threading
from contextlib import contextmanager
from typing import Any, Iterator

__all__ = ["sigint_remembered", "raise_if_interrupted", "committed"]

_pending = threading.Event()
_committed = threading.Event()


def _remember(signum: int, frame: Any) -> None:
    _pending.set()
    if not _committed.is_set():
        raise KeyboardInterrupt


@contextmanager
def sigint_remembered() -> Iterator[None]:
    """While inside, SIGINT raises KeyboardInterrupt as usual and is also
    remembered for :func:`raise_if_interrupted`. Only in the main thread and
    where Python's own handler is in place: a SIGINT that is ignored (a
    background job) or handled by the caller is left as it is, and an inner
    use inside an outer one changes nothing."""
    if threading.current_thread() is not threading.main_thread() or signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        yield
        return
    _pending.clear()
    _committed.clear()
    previous = signal.signal(signal.SIGINT, _remember)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        _pending.clear()
        _committed.clear()


def raise_if_interrupted() -> None:
    """Raise KeyboardInterrupt if a SIGINT came inside :func:`sigint_remembered`
    before :func:`committed` (the first one may have been swallowed by a library)."""
    if _pending.is_set() and not _committed.is_set():
        raise KeyboardInterrupt


def committed() -> None:
    """The output is complete and goes into place now: from here on (to the
    end of :func:`sigint_remembered`) a SIGINT no longer interrupts."""
    if signal.getsignal(signal.SIGINT) is _remember:
        raise_if_interrupted()
        _committed.set()
