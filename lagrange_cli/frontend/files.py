"""System files: finding one (a path or a bundled system), naming it, reading and validating it."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

from lagrange_cli.errors import Span, fail
from lagrange_cli.expr import _closest
from lagrange_cli.frontend.nodes import SystemSpec
from lagrange_cli.frontend.reader import Reader
from lagrange_cli.frontend.source import _compose

MAX_FILE_BYTES = 1_000_000


def bundled_systems() -> Path:
    """The folder of bundled systems: inside the installed package, or beside it in a checkout."""
    here = Path(__file__).resolve().parent.parent  # lagrange_cli/, above this frontend/ folder
    for candidate in (here / "systems", here.parent / "systems"):
        if candidate.is_dir():
            return candidate
    return here / "systems"


def resolve(name: str) -> Path:
    """A path to a system file: `name` itself if it exists, else a bundled system of that name.
    A name no file can have (a NUL byte, too long, not UTF-8) is a `LagrangeError`, not a crash."""
    from lagrange_cli.files import check_name, shown

    path = Path(check_name(name))
    if os.path.lexists(path):
        return path  # whatever it is: `load` says why it cannot be read
    folder = bundled_systems()
    if "/" not in name and name not in ("", ".", ".."):
        for candidate in (folder / name, folder / f"{name}.yaml"):
            if candidate.is_file():
                return candidate
    known = sorted(p.stem for p in folder.glob("*.yaml"))
    hint = _closest(path.stem, known)
    raise fail(None, f"no such file: {shown(name)}, and no bundled system of that name", f"a path to a .yaml file or one of: {', '.join(known)}" + (f" (did you mean '{hint}'?)" if hint else ""))


def shown_name(path: str | Path) -> str:
    """How messages and reports name a system file: a bundled one (an absolute path into the
    installed package, as `resolve` finds it) as `systems/<name>.yaml`, any other path as given."""
    text = str(path)
    if os.path.isabs(text):
        folder = bundled_systems()
        if Path(text).parent == folder:
            return f"{folder.name}/{Path(text).name}"
    return text


def load(path: str | Path) -> SystemSpec:
    """Read and validate a system file; raises `SpecError` listing every problem. Only a regular
    file is read (a FIFO, a device or a directory is refused) and at most MAX_FILE_BYTES of it.
    Messages and the spec name it by `shown_name`."""
    from lagrange_cli.files import read_limited

    raw = read_limited(path, MAX_FILE_BYTES)
    name = shown_name(path)
    if len(raw) > MAX_FILE_BYTES:
        raise fail(Span(name, 1, 1), f"file is over {MAX_FILE_BYTES} bytes", f"a system file under {MAX_FILE_BYTES} bytes")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise fail(Span(name, 1, 1), f"file is not UTF-8 (byte {exc.start})", "a UTF-8 text file") from None
    return parse(text, name)


def parse(text: str, filename: str = "<string>") -> SystemSpec:
    """Validate system-file text; `filename` is used in messages."""
    root = _compose(text, filename)
    return Reader(filename, text).read(root)


def iter_files(paths: list[str]) -> Iterator[Path]:
    """System files named by paths, directories (their *.yaml, sorted) and globs."""
    import glob

    for item in paths:
        path = Path(item)
        if path.is_dir():
            yield from sorted(path.glob("*.yaml"))
        elif any(c in item for c in "*?["):
            yield from (Path(p) for p in sorted(glob.glob(item, recursive=True)))
        else:
            yield resolve(item)
