"""One worker thread per bus or port, so blocking I/O never runs on the event loop."""

from __future__ import annotations

import asyncio
import functools
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import ParamSpec, TypeVar

P = ParamSpec("P")
T = TypeVar("T")


class DeviceWorker:
    """A single thread that runs every blocking call for one bus or port, in order.

    One thread (not a pool) matters for I2C: a mux selection and the sensor transfers behind
    it must not interleave with another sensor's, and a single queue guarantees that without
    a lock as long as each sensor's work is submitted as one call.
    """

    def __init__(self, name: str) -> None:
        self.name = name
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix=name)

    async def call(self, fn: Callable[P, T], *args: P.args, **kwargs: P.kwargs) -> T:
        loop = asyncio.get_running_loop()
        return await loop.run_in_executor(self._executor, functools.partial(fn, *args, **kwargs))

    def close(self) -> None:
        """Stop accepting work; a call already running finishes in its thread."""
        self._executor.shutdown(wait=False, cancel_futures=True)
