"""Exponential backoff for retrying hardware: fast first retries, bounded later ones."""

from __future__ import annotations


class Backoff:
    """Delays ``initial_s, 2*initial_s, ...`` capped at ``max_s``; :meth:`reset` on success."""

    def __init__(self, initial_s: float = 0.25, max_s: float = 8.0) -> None:
        if not 0 < initial_s <= max_s:
            raise ValueError(f"backoff needs 0 < initial_s <= max_s, got {initial_s}, {max_s}")
        self.initial_s = initial_s
        self.max_s = max_s
        self._next = initial_s

    def next_delay(self) -> float:
        delay = self._next
        self._next = min(self._next * 2, self.max_s)
        return delay

    def reset(self) -> None:
        self._next = self.initial_s
