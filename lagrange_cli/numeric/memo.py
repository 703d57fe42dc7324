"""Values computed once per model object, kept on the object itself.

`functools.cached_property` does this for `Model`'s own derived values; numeric code caches its
own (the evaluated constraint rows, a checked model, the initial rates of a study) the same way:
in the object's `__dict__`, so that a cache entry lives and dies with its model. A dictionary
keyed by `id(model)` would hand a new model the entry of a dead one that had the same id.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Hashable
from concurrent.futures import Future
from typing import Any, TypeVar

T = TypeVar("T")
SLOT = "_numeric_memo"
AHEAD_SLOT = "_numeric_ahead"


def once(owner: Any, key: Hashable, compute: Callable[[], T]) -> T:
    """compute() the first time for this owner and key; the same value after that. A value started
    `ahead` is waited for (its exception raised here, as compute()'s would be)."""
    store: dict[Hashable, Any] = owner.__dict__.setdefault(SLOT, {})  # beside cached_property's entries; frozen dataclasses allow it
    if key not in store:
        started: Future[Any] | None = owner.__dict__.get(AHEAD_SLOT, {}).pop(key, None)
        store[key] = started.result() if started is not None else compute()
    return store[key]  # type: ignore[no-any-return]


def ahead(owner: Any, key: Hashable, compute: Callable[[], object]) -> None:
    """compute() started now in a thread of its own, for `once` with this owner and key to take up: a value
    the caller will ask for next, computed beside what it does meanwhile. Only for computations that release
    the GIL (compiled runs: numba's kernels are `nogil`) and touch no process-wide state (scipy's runs set
    warnings filters); deterministic, so the value is the one `once` would compute. `settle` waits for every
    value started ahead (a measured run must not share the machine with one)."""
    store: dict[Hashable, Any] = owner.__dict__.setdefault(SLOT, {})
    pending: dict[Hashable, Future[Any]] = owner.__dict__.setdefault(AHEAD_SLOT, {})
    if key in store or key in pending:
        return
    future: Future[Any] = Future()
    pending[key] = future

    def work() -> None:
        try:
            future.set_result(compute())
        except BaseException as error:  # handed to the thread that asks for the value
            future.set_exception(error)

    threading.Thread(target=work, name="lagrange-ahead", daemon=True).start()


def settle(owner: Any) -> None:
    """Wait for every value started `ahead` for this owner; they stay for `once` to take up."""
    for future in list(owner.__dict__.get(AHEAD_SLOT, {}).values()):
        future.exception()  # waits; an exception stays with the future for `once` to raise
