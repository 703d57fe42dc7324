"""Values computed once per model object, kept on the object itself.

`functools.cached_property` does this for `Model`'s own derived values; numeric code caches its
own (the evaluated constraint rows, a checked model, the initial rates of a study) the same way:
in the object's `__dict__`, so that a cache entry lives and dies with its model. A dictionary
keyed by `id(model)` would hand a new model the entry of a dead one that had the same id.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable
from typing import Any, TypeVar

T = TypeVar("T")
SLOT = "_numeric_memo"


def once(owner: Any, key: Hashable, compute: Callable[[], T]) -> T:
    """compute() the first time for this owner and key; the same value after that."""
    store: dict[Hashable, Any] = owner.__dict__.setdefault(SLOT, {})  # beside cached_property's entries; frozen dataclasses allow it
    if key not in store:
        store[key] = compute()
    return store[key]  # type: ignore[no-any-return]
