"""Atomic file output: readers see the old file or the whole new one, never half of one."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import IO

from lagrange_cli.errors import LagrangeError


def check_writable(path: Path) -> None:
    """Raise `LagrangeError` unless a file can be written at `path` (its folder exists and is
    writable, and `path` is not a folder): checked before a command does its work, so that a
    mistyped output path costs nothing and leaves nothing half-done."""
    target = Path(path).resolve()
    folder = target.parent
    if target.is_dir():
        raise LagrangeError(f"cannot write {path}: it is a directory\n  expected: a file name, such as {Path(path) / 'out'}")
    if not folder.is_dir():
        raise LagrangeError(f"cannot write {path}: the directory {folder} does not exist\n  expected: a path in an existing directory (create it first)")
    if not os.access(folder, os.W_OK):
        raise LagrangeError(f"cannot write {path}: the directory {folder} is not writable")


def atomic_write(path: Path, write: Callable[[IO[bytes]], object]) -> None:
    """Write through `write(stream)` to a temporary file beside `path`, then rename it over `path`;
    an operating-system error (no such directory, no space, no permission) is a `LagrangeError`."""
    path = Path(path).resolve()
    try:
        handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    except OSError as error:
        raise LagrangeError(f"cannot write {path}: {error.strerror}") from None
    try:
        with os.fdopen(handle, "wb") as stream:
            write(stream)
        os.replace(temporary, path)
    except OSError as error:
        Path(temporary).unlink(missing_ok=True)
        raise LagrangeError(f"cannot write {path}: {error.strerror}") from None
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def write_text(path: Path, text: str) -> None:
    """`text` (UTF-8) to `path`, atomically."""
    atomic_write(path, lambda stream: stream.write(text.encode("utf-8")))
