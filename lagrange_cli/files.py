"""Files in and out, safely: names checked, only regular files read (and a bounded number of
bytes), outputs written atomically (readers see the old file or the whole new one, never half of
one) with the old file's mode or the umask's, and never over an input or a device.

Promises (the README's "Files" paragraph):
- an input must be a regular file (a FIFO, a device, a directory or a socket is refused, never
  waited on or read without end) and is read up to a size limit;
- an output replaces a regular file atomically, keeping that file's permission bits; a new file
  gets `0666 & ~umask`, as `open()` would give it;
- an output that names a character device (`/dev/null`, a terminal) or a FIFO with a reader is
  written in place, never replaced by a regular file; a FIFO with no reader, a block device or a
  socket is refused; `/dev/stdout`, `/dev/stderr`, `/dev/fd/N` are written through that open
  descriptor, wherever the shell pointed it;
- `-` as an output is standard output (the CLI handles it; here it is an ordinary name);
- an output that is one of the command's inputs, or that two outputs of one command share, is
  refused before any work;
- a name with a NUL byte, bytes that are not UTF-8, a component over 255 bytes or a total over
  4095 bytes is refused with a message, never a traceback.
"""

from __future__ import annotations

import errno
import io
import os
import re
import stat
import tempfile
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import IO

from lagrange_cli.errors import Diagnostic, LagrangeError, fail, printable

# Names of this process's open descriptors: written through the descriptor itself.
_DESCRIPTOR = re.compile(r"/dev/((?P<std>stdout|stderr)|fd/(?P<fd>[0-9]+))\Z|/proc/(?P<pid>self|[0-9]+)/fd/(?P<pfd>[0-9]+)\Z")
NAME_MAX = 255  # bytes in one path component (Linux, macOS)
PATH_MAX = 4095  # bytes in a whole path


def shown(path: str | os.PathLike[str]) -> str:
    """A path as it appears in a message: quoted, with control characters and undecodable bytes
    written as visible escapes."""
    return "'" + printable(os.fspath(path), keep="") + "'"


def _bare(path: str | os.PathLike[str]) -> str:
    """A path in an output message (unquoted, as the messages always had it), made printable."""
    return printable(os.fspath(path), keep="")


def _error(message: str, expected: str = "") -> LagrangeError:
    """An error about a file name or an output; one about reading a system file is a `SpecError`
    (`fail`), like every other problem with a system file."""
    return LagrangeError(Diagnostic(None, message, expected).render())


def check_name(path: str | os.PathLike[str], verb: str = "read") -> str:
    """`path` as a string, or a `LagrangeError` when no file can have that name: a NUL byte (which
    `os` functions answer with a ValueError), bytes that are not UTF-8 (they reach Python as lone
    surrogates), a component over NAME_MAX bytes or a path over PATH_MAX bytes. A name to read is
    a system file's: the error is then a `SpecError`."""
    name = os.fspath(path)
    problem = _name_problem(name)
    if problem is None:
        return name
    message, expected = f"cannot {verb} {shown(_shortened(name))}: {problem[0]}", problem[1]
    raise fail(None, message, expected) if verb == "read" else _error(message, expected)


def _name_problem(name: str) -> tuple[str, str] | None:
    if not name:
        return "the file name is empty", "a file name"
    if "\0" in name:
        return "the file name contains a NUL byte", "a file name without NUL bytes"
    try:
        encoded = name.encode("utf-8")
    except UnicodeEncodeError:
        return "the file name is not valid UTF-8", "a file name in UTF-8 (rename the file)"
    if len(encoded) > PATH_MAX or any(len(part) > NAME_MAX for part in encoded.split(b"/")):
        return "the file name is too long", f"at most {NAME_MAX} bytes per folder or file name and {PATH_MAX} in all"
    return None


def _shortened(name: str, limit: int = 80) -> str:
    return name if len(name) <= limit else f"{name[: limit // 2]}...{name[-limit // 2 :]}"


def read_limited(path: str | os.PathLike[str], limit: int) -> bytes:
    """The bytes of the regular file `path`, at most `limit + 1` of them (so that a caller sees a
    file that is too long without reading all of it). The file is opened without blocking (a FIFO
    does not wait for a writer) and its type is taken from the open descriptor (no race between a
    check and the open): anything but a regular file is refused."""
    name = check_name(path)
    try:
        descriptor = os.open(name, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY | getattr(os, "O_CLOEXEC", 0))
    except OSError as error:
        raise fail(None, f"cannot read {shown(name)}: {error.strerror}", "a readable system file") from None
    try:
        kind = _kind(os.fstat(descriptor).st_mode)
        if kind != "a regular file":
            raise fail(None, f"cannot read {shown(name)}: it is {kind}", "a regular system file (a .yaml file)")
        chunks, size = [], 0
        while size <= limit:
            chunk = os.read(descriptor, min(limit + 1 - size, 1 << 20))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
        return b"".join(chunks)
    except OSError as error:
        raise fail(None, f"cannot read {shown(name)}: {error.strerror}", "a readable system file") from None
    finally:
        os.close(descriptor)


def _kind(mode: int) -> str:
    kinds = (
        (stat.S_ISREG, "a regular file"),
        (stat.S_ISDIR, "a directory"),
        (stat.S_ISFIFO, "a FIFO (named pipe)"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISSOCK, "a socket"),
    )
    return next((text for test, text in kinds if test(mode)), "not a regular file")


def _stat(name: str) -> os.stat_result | None:
    """`os.stat` (following links), or None when nothing is there yet."""
    try:
        return os.stat(name)
    except FileNotFoundError:
        return None
    except NotADirectoryError:
        raise _error(f"cannot write {_bare(name)}: a part of the path is not a directory", "a path in an existing directory") from None
    except OSError as error:
        raise _error(f"cannot write {_bare(name)}: {error.strerror}") from None


def check_writable(path: str | os.PathLike[str]) -> None:
    """Raise `LagrangeError` unless a file can be written at `path` (its folder exists and is
    writable, and `path` is not a folder, a block device or a socket): checked before a command
    does its work, so that a mistyped output path costs nothing and leaves nothing half-done."""
    name = check_name(path, "write")
    found = _stat(name)
    if found is not None and not stat.S_ISREG(found.st_mode):
        if stat.S_ISDIR(found.st_mode):
            raise _error(f"cannot write {_bare(name)}: it is a directory", f"a file name, such as {_bare(os.path.join(name, 'out'))}")
        if not (stat.S_ISCHR(found.st_mode) or stat.S_ISFIFO(found.st_mode)):
            raise _error(f"cannot write {_bare(name)}: it is {_kind(found.st_mode)}", "a regular file, a character device such as /dev/null, a FIFO, or - for standard output")
        return  # written in place (see `atomic_write`)
    folder = os.path.dirname(os.path.realpath(name))
    if not os.path.isdir(folder):
        raise _error(f"cannot write {_bare(name)}: the directory {_bare(folder)} does not exist", "a path in an existing directory (create it first)")
    if not os.access(folder, os.W_OK):
        raise _error(f"cannot write {_bare(name)}: the directory {_bare(folder)} is not writable")


def same_file(a: str | os.PathLike[str], b: str | os.PathLike[str]) -> bool:
    """Whether `a` and `b` name one file: the same inode when both exist (through links and any
    spelling), else the same resolved path."""
    try:
        first, second = os.stat(a), os.stat(b)
    except (OSError, ValueError):
        try:
            return os.path.realpath(a) == os.path.realpath(b)
        except (OSError, ValueError):
            return False
    return (first.st_dev, first.st_ino) == (second.st_dev, second.st_ino)


def check_outputs(outputs: Iterable[tuple[str, str | os.PathLike[str]]], inputs: Iterable[str | os.PathLike[str]] = ()) -> None:
    """Every output (option, path) can be written, none of them is an input, and no two share a
    file (a device such as /dev/null may take several); raises `LagrangeError` naming the option."""
    outputs, inputs = list(outputs), list(inputs)
    for option, path in outputs:
        check_writable(path)
        for source in inputs:
            if same_file(path, source):
                raise _error(f"{option} {shown(path)} is the input file {shown(source)}: writing it would destroy the input", "a different output file")
    for index, (option, path) in enumerate(outputs):
        for other, earlier in outputs[:index]:
            found = _stat(os.fspath(path))
            if same_file(path, earlier) and not (found is not None and stat.S_ISCHR(found.st_mode)):
                raise _error(f"{other} and {option} both write {shown(path)}", "a different file for each output")


def atomic_write(path: str | os.PathLike[str], write: Callable[[IO[bytes]], object], *, private: bool = False) -> None:
    """Write through `write(stream)` to a temporary file beside `path`, then rename it over `path`
    with the old file's permission bits (or `0666 & ~umask` for a new file); a character device or
    a FIFO is written in place instead (after the whole content is made). An operating-system
    error (no such directory, no space, no permission) is a `LagrangeError`. `private`: mode 0600
    whatever was there (a cache of generated code)."""
    name = check_name(path, "write")
    found = _stat(name)
    descriptor = _descriptor(name)
    if found is not None and (stat.S_ISCHR(found.st_mode) or stat.S_ISFIFO(found.st_mode) or descriptor is not None):
        buffer = io.BytesIO()
        write(buffer)
        if descriptor is not None:
            _write_descriptor(name, descriptor, buffer.getvalue())
        else:
            _write_in_place(name, buffer.getvalue())
        return
    if found is not None and not stat.S_ISREG(found.st_mode):
        check_writable(name)  # raises: a directory, a block device, a socket
    target = os.path.realpath(name)  # through a symbolic link: the link stays, its target is replaced
    mode = 0o600 if private else found.st_mode & 0o777 if found is not None else 0o666 & ~_umask()  # never set-id or sticky bits
    try:
        handle, temporary = tempfile.mkstemp(dir=os.path.dirname(target), prefix=f".{os.path.basename(target)}.", suffix=".tmp")
    except OSError as error:
        raise _error(f"cannot write {_bare(name)}: {error.strerror}") from None
    try:
        with os.fdopen(handle, "wb") as stream:
            write(stream)
            os.fchmod(stream.fileno(), mode)
        os.replace(temporary, target)
    except OSError as error:
        Path(temporary).unlink(missing_ok=True)
        raise _error(f"cannot write {_bare(name)}: {error.strerror}") from None
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def _descriptor(name: str) -> int | None:
    """The descriptor number that `name` stands for in this process (`/dev/stdout`, `/dev/fd/3`,
    `/proc/self/fd/3`), or None."""
    found = _DESCRIPTOR.match(os.path.abspath(name))
    if found is None or found.group("pid") not in (None, "self", str(os.getpid())):
        return None
    return {"stdout": 1, "stderr": 2}.get(found.group("std") or "", int(found.group("fd") or found.group("pfd") or 0))


def _write_descriptor(name: str, number: int, data: bytes) -> None:
    """`data` through the already open descriptor `number`, as the shell set it up (a pipe, a
    terminal, a file opened for appending or truncated): nothing is reopened or replaced."""
    import sys

    stream = {1: sys.stdout, 2: sys.stderr}.get(number)
    try:
        if stream is not None:
            stream.flush()
            stream.buffer.write(data)
            stream.flush()
            return
        view = memoryview(data)
        while view:
            view = view[os.write(number, view) :]
    except (OSError, ValueError, AttributeError) as error:
        raise _error(f"cannot write {_bare(name)}: {getattr(error, 'strerror', None) or error}") from None


def _write_in_place(name: str, data: bytes) -> None:
    """`data` into an existing character device or FIFO, which stays what it is; a FIFO that no
    process reads is refused rather than waited on."""
    import fcntl  # POSIX only, like FIFOs

    try:
        descriptor = os.open(name, os.O_WRONLY | os.O_NONBLOCK | os.O_NOCTTY | getattr(os, "O_CLOEXEC", 0))
    except OSError as error:
        if error.errno == errno.ENXIO and stat.S_ISFIFO(os.stat(name).st_mode):
            raise _error(f"cannot write {_bare(name)}: it is a FIFO that no process is reading", "a regular file, or a FIFO with a reader") from None
        raise _error(f"cannot write {_bare(name)}: {error.strerror}") from None
    try:
        mode = os.fstat(descriptor).st_mode
        if not (stat.S_ISCHR(mode) or stat.S_ISFIFO(mode)):
            raise _error(f"cannot write {_bare(name)}: it changed while the output was made", "a file nothing else is writing")
        fcntl.fcntl(descriptor, fcntl.F_SETFL, fcntl.fcntl(descriptor, fcntl.F_GETFL) & ~os.O_NONBLOCK)
        view = memoryview(data)
        while view:
            view = view[os.write(descriptor, view) :]
    except OSError as error:
        raise _error(f"cannot write {_bare(name)}: {error.strerror}") from None
    finally:
        os.close(descriptor)


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_text(path: str | os.PathLike[str], text: str, *, private: bool = False) -> None:
    """`text` (UTF-8) to `path`, atomically (`private`: mode 0600)."""
    atomic_write(path, lambda stream: stream.write(text.encode("utf-8")), private=private)
