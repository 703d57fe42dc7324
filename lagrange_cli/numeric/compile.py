"""A system's numeric functions as an importable module, cached on disk.

The generated source (codegen.py) is written to `$LAGRANGE_CACHE_DIR`,
`$XDG_CACHE_HOME/lagrange` or `~/.cache/lagrange`, under a name made from a hash of the source
itself (so the key covers everything the file contains, title and file name included) and
of the versions that run it. A cached file is used only when its bytes equal the source just
generated; a missing, truncated, corrupted or tampered file is written anew. The module is then
executed from that verified source, compiled under the file's name (so numba's `cache=True`
finds its machine code beside it): never from what the file might hold a moment later, never
from a `.pyc`, never `eval` of file text. For the numba target the
integration loops (kernels.py) are copied there too, so numba keeps all machine code beside
those files (`cache=True`): the loops compile once per machine, a system's few functions
once per system, and later runs load them. Modules imported once are kept for the process.
"""

from __future__ import annotations

import atexit
import functools
import hashlib
import importlib.util
import os
import stat
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from types import ModuleType

import sympy as sp

from lagrange_cli import __version__
from lagrange_cli.emit.python import SOLVE, docstring
from lagrange_cli.errors import LagrangeError
from lagrange_cli.files import write_text
from lagrange_cli.model import Model
from lagrange_cli.numeric import codegen

JIT_FOOTER = """

# Every function above, compiled by numba when first used; machine code is cached beside this file.
from numba import njit as _njit  # noqa: E402

for _name, _value in list(globals().items()):
    if type(_value).__name__ == "function" and _value.__module__ == __name__:
        globals()[_name] = _njit(cache=True, error_model="numpy")(_value)
"""

NUMBA_HINT = "install it with `pip install 'lagrange-cli[fast]'`"

_LOADED: dict[str, ModuleType] = {}
_SOURCES: dict[tuple[int, str, bool, str], tuple[Model, str, str]] = {}


@dataclass(frozen=True)
class Functions:
    """An imported module of a system's functions, and what it cost to get it."""

    module: ModuleType
    target: str
    path: Path
    kernels: ModuleType | None
    generate_seconds: float
    """Generating and writing the source (0 when a verified copy was on disk or already imported)."""
    import_seconds: float
    """Importing the module (with numba itself for the numba target)."""
    reused: bool
    """True when the source file was already on disk or the module already imported."""


def cache_dir() -> Path:
    """Where generated modules and numba's machine code live."""
    configured = os.environ.get("LAGRANGE_CACHE_DIR")
    if configured:
        return Path(configured)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "lagrange"


def numba_available() -> bool:
    """True when numba can be imported (checked without importing it)."""
    return importlib.util.find_spec("numba") is not None


def fingerprint(model: Model, target: str, jacobian: bool, event: sp.Expr | None) -> str:
    """The cache key of the module: a hash of its whole source (title and file name included,
    the file's function definitions written out) with lagrange's, Python's and numba's versions
    and the code generator's own source. Generating the source costs milliseconds; it is
    remembered per model object (which the memo keeps alive, so that its id is not reused)."""
    return _generated(model, target, jacobian, event)[1]


def build(model: Model, target: str, jacobian: bool = False, event: sp.Expr | None = None) -> Functions:
    """The system's functions for `target` ("numba" or "python"), written only when not cached."""
    if target == "numba" and not numba_available():
        raise LagrangeError(f"the compiled path needs numba: {NUMBA_HINT}, or use `--backend python`")
    start = time.perf_counter()
    kernels = kernels_module() if target == "numba" else None
    began = time.perf_counter()
    text, key = _generated(model, target, jacobian, event)
    name = f"lagrange_{target}_{key}"
    path = cache_dir() / f"{name}.py"
    if name in _LOADED:
        return Functions(_LOADED[name], target, path, kernels, 0.0, 0.0, True)
    reused = _cached(path, text)
    written = time.perf_counter() - began if not reused else 0.0  # a verified file on disk costs what loading costs
    module = _load(name, path, text)
    _LOADED[name] = module
    return Functions(module, target, path, kernels, written, time.perf_counter() - start - written, reused)


def kernels_module() -> ModuleType:
    """The compiled integration loops (kernels.py), imported from their copy in the cache."""
    name = kernels_name()
    if name not in _LOADED:
        path = cache_dir() / f"{name}.py"
        text = _kernels_source()
        _cached(path, text)
        _LOADED[name] = _load(name, path, text)
    return _LOADED[name]


WARM_CODE = "import sys\nfrom lagrange_cli.numeric import compile\nkernels = compile.kernels_module()\nfor name in sys.argv[1:]:\n    kernels.compiled(name)\n"
"""What the process that compiles kernels ahead runs (`warm_kernels`): fixed code, the kernels' names its only arguments."""
_WARMING: dict[tuple[str, str], subprocess.Popen[bytes]] = {}
"""The kernel entry points being compiled ahead, by cache folder and name: the process compiling them."""
_STARTED: list[subprocess.Popen[bytes]] = []
"""Every process started to compile ahead, stopped at exit if still running (`_stop_warming`)."""


def warm_kernels(names: Sequence[str], later: bool = False) -> None:
    """Compile the kernel entry points `names` that numba's cache does not hold yet in a process of their own,
    in that order, while this one goes on (compiling the ones it needs first): numba compiles under the GIL, so
    only a second process uses the machine's second core (each group a method needs together, one process: Radau's
    and the symplectic method's apart, so that waiting for one never waits for the other). `later`: a group needed
    after the others, queued while a process compiling ahead is still running and started when none is, or when this
    one is about to wait for a kernel (`kernel_entry`: its core idle); started at once, a third compiling process on a
    two-core machine slowed the two the command needs first (the first Kepler `stress`, e = 0.9, took 35-43 s; queued,
    30-33 s).
    The first `stress` on a machine compiles its explicit loops (erk_start, erk_run: about 9 s of CPU) here and
    Radau's (radau_start, radau_run: about 15 s) ahead. `kernel_entry` waits for a kernel being compiled ahead rather
    than compiling it a second time; the process is stopped when this one exits (numba writes its cache files whole,
    by renaming). Nothing is started without numba, for kernels already cached, or where LAGRANGE_NO_WARM is set."""
    if not names or not numba_available() or os.environ.get("LAGRANGE_NO_WARM") or not sys.executable:
        return
    kernels_module()  # the copy the process imports, written here first
    folder = str(cache_dir())
    missing = [name for name in dict.fromkeys(names) if (folder, name) not in _WARMING and (folder, name) not in _QUEUED and not kernel_cached(name)]
    if not missing:
        return
    if later and any(process.poll() is None for process in _STARTED):
        group = tuple(missing)
        for name in missing:
            _QUEUED[(folder, name)] = group
        return
    _start(folder, missing)


_QUEUED: dict[tuple[str, str], tuple[str, ...]] = {}
"""The kernel entry points queued to be compiled ahead (`warm_kernels(later=True)`), by cache folder and name: their group."""


def _start(folder: str, names: Sequence[str]) -> None:
    environment = {**os.environ, "LAGRANGE_CACHE_DIR": folder, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p)}
    try:
        process = subprocess.Popen([sys.executable, "-c", WARM_CODE, *names], stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=environment)
    except OSError:
        return  # no second process: each kernel is compiled here when first needed, as without it
    if not _STARTED:
        atexit.register(_stop_warming)
    _STARTED.append(process)
    for name in names:
        _WARMING[(folder, name)] = process


def _release(waiting: bool) -> None:
    """Start the queued groups (`warm_kernels(later=True)`) once no process compiling ahead is running, or now that
    this one is `waiting` for a kernel."""
    if _QUEUED and (waiting or all(process.poll() is not None for process in _STARTED)):
        groups = dict.fromkeys((folder, group) for (folder, _), group in _QUEUED.items())
        _QUEUED.clear()
        for folder, group in groups:
            _start(folder, group)


def kernel_cached(name: str) -> bool:
    """Whether numba's cache beside the kernels' copy holds machine code of the entry point `name` (its index file)."""
    return any((cache_dir() / "__pycache__").glob(f"{kernels_name()}.{name}-*.nbi"))


WARM_POLL = 0.05
"""Seconds between looks at the cache while a kernel this process needs is being compiled ahead."""


def kernel_entry(kernels: ModuleType, name: str) -> object:
    """`kernels.compiled(name)`, after waiting for the process compiling it ahead (`warm_kernels`), if there is
    one, to write it to the cache (or to end, having failed): then it is loaded, not compiled again. About to wait
    (or to compile a kernel queued for later), the queued groups start: this process's core is idle meanwhile."""
    key = (str(cache_dir()), name)
    if key in _QUEUED:
        _release(waiting=True)
    process = _WARMING.pop(key, None)
    _release(waiting=process is not None and process.poll() is None and not kernel_cached(name))
    while process is not None and process.poll() is None and not kernel_cached(name):
        time.sleep(WARM_POLL)
    return kernels.compiled(name)


_COMPILING = [0.0]


def note_compiling(seconds: float) -> None:
    """Count `seconds` spent compiling, loading or waiting for compiled code (`integrators._compile`)."""
    _COMPILING[0] += seconds


def compiling_seconds() -> float:
    """Seconds this process has spent so far compiling, loading or waiting for compiled code: a one-off cost
    (the first run on a machine compiles the loops, the first on a system its functions), which an estimate of
    the time left does not extrapolate."""
    return _COMPILING[0]


def _stop_warming() -> None:
    for process in _STARTED:
        if process.poll() is None:
            process.terminate()
            try:
                process.wait(5)
            except subprocess.TimeoutExpired:
                process.kill()
    _WARMING.clear()
    _QUEUED.clear()


def cached_module(prefix: str, text: str) -> ModuleType:
    """A module of compiled loops given as source `text` (such as ensemble.py's batch loop), written
    to the cache under `prefix` and a hash of the text, verified and imported as the kernels are,
    so that numba's `cache=True` keeps its machine code beside it."""
    name = prefix + hashlib.sha256(text.encode()).hexdigest()[:20]
    if name not in _LOADED:
        path = cache_dir() / f"{name}.py"
        _cached(path, text)
        _LOADED[name] = _load(name, path, text)
    return _LOADED[name]


KERNEL_CONSTANTS = ("status.py", "tableaux.py")
"""The modules whose values kernels.py imports (status codes, record indices, step-control constants, tableaux):
numba freezes them into the machine code it caches, so they are part of the kernels' cache key (`kernels_name`)."""


@functools.cache
def kernels_name() -> str:
    """The module name of the kernels' copy: a hash of their source, of the modules whose constants they take
    (KERNEL_CONSTANTS: numba's cache, keyed by the copy's file alone, would keep machine code compiled with the old
    values of a changed constant) and of the versions that compile it."""
    numeric = resources.files("lagrange_cli.numeric")
    constants = "".join(numeric.joinpath(name).read_text(encoding="utf-8") for name in KERNEL_CONSTANTS)
    return "lagrange_kernels_" + hashlib.sha256("\x00".join([_kernels_source(), constants, _numba_version("numba"), sys.version]).encode()).hexdigest()[:20]


def module_source(model: Model, target: str, jacobian: bool, event: sp.Expr | None) -> str:
    """The whole module: a header, the linear solver (the kernels' for numba), the system's functions.
    The title and file name enter it only through `docstring`, as data."""
    header = docstring(f"{model.title}: numeric functions generated by lagrange {__version__} from {Path(model.source).name} ({target}). Do not edit.") + "\n\n"
    body = codegen.source(model, target, jacobian, event)
    if target == "numba":
        return header + f"from {kernels_name()} import lu_solve as _lu_solve\n\n" + body + JIT_FOOTER
    imports = "import numpy\n\n\n" if jacobian else ""
    return header + imports + SOLVE + "\n\n\n" + body


def _generated(model: Model, target: str, jacobian: bool, event: sp.Expr | None) -> tuple[str, str]:
    """The module's source and its cache key, remembered per model object."""
    memo = (id(model), target, jacobian, str(event))
    if memo not in _SOURCES:
        text = module_source(model, target, jacobian, event)
        try:
            compile(text, "<generated>", "exec", dont_inherit=True)
        except (SyntaxError, ValueError) as error:  # a bug in the generator, never the file's doing: stop before caching it
            raise LagrangeError(f"{model.source}: the generated code does not compile ({error}); please report this") from None
        parts = [__version__, _generator_source(), sys.version, _numba_version(target), text]
        _SOURCES[memo] = (model, text, hashlib.sha256("\x00".join(parts).encode()).hexdigest()[:24])
    _, text, key = _SOURCES[memo]
    return text, key


@functools.cache
def _kernels_source() -> str:
    return resources.files("lagrange_cli.numeric").joinpath("kernels.py").read_text(encoding="utf-8")


@functools.cache
def _generator_source() -> str:
    """The code that writes the generated modules: a fix to it must not reuse modules cached before."""
    files = [("lagrange_cli.numeric", "codegen.py"), ("lagrange_cli.emit", "python.py"), ("lagrange_cli.emit", "printer.py"), ("lagrange_cli.emit", "common.py"), ("lagrange_cli", "algebra.py")]
    return "".join(resources.files(package).joinpath(name).read_text(encoding="utf-8") for package, name in files)


@functools.cache
def _numba_version(target: str) -> str:
    if target != "numba":
        return ""
    from importlib import metadata

    try:
        return metadata.version("numba")
    except metadata.PackageNotFoundError:
        return ""


def _cached(path: Path, text: str) -> bool:
    """True when `path` is a regular file holding exactly `text`; otherwise (missing, truncated,
    corrupted, tampered with, a symlink, a FIFO or a device) it is replaced, atomically, by a
    file of `text`, so that no wrong file stays in the cache. Only a regular file of the right
    size is read. The cache folder is created private to the user (0700)."""
    data = text.encode("utf-8")
    try:
        found = path.lstat()
    except OSError:
        found = None
    if found is not None and stat.S_ISREG(found.st_mode) and found.st_size == len(data) and path.read_bytes() == data:
        return True
    try:
        if found is not None and not stat.S_ISREG(found.st_mode):
            path.unlink()  # the link itself, never what it points to: the new file is written in its place
        path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
        write_text(path, text)
    except (OSError, LagrangeError) as error:
        reason = error.strerror if isinstance(error, OSError) else str(error)
        raise LagrangeError(f"cannot write generated code to {path.parent} ({reason}); set LAGRANGE_CACHE_DIR to a writable directory") from None
    return False


def _load(name: str, path: Path, text: str) -> ModuleType:
    """The module `name` executed from `text`, the source just generated or verified, compiled
    under `path`'s name (where numba keeps its machine code): never from whatever the file
    holds by the time of the import, and never from a stale `.pyc`."""
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None:
        raise LagrangeError(f"cannot import the generated module {path}; delete {path.parent} and try again")
    module = importlib.util.module_from_spec(spec)
    code = compile(text, str(path), "exec", dont_inherit=True)
    sys.modules[name] = module
    try:
        exec(code, module.__dict__)  # generated code, every piece of file text in it escaped as data
    except BaseException:
        del sys.modules[name]
        raise
    return module
