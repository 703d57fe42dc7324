"""A system's numeric functions as an importable module, cached on disk.

The generated source (codegen.py) is written once to `$LAGRANGE_CACHE_DIR`,
`$XDG_CACHE_HOME/lagrange` or `~/.cache/lagrange`, under a name made from a hash of
everything it depends on, and imported from there: never `eval`. For the numba target the
integration loops (kernels.py) are copied there too, so numba keeps all machine code beside
those files (`cache=True`): the loops compile once per machine, a system's few functions
once per system, and later runs load them. Modules imported once are kept for the process.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import os
import sys
import time
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from types import ModuleType

import sympy as sp

from lagrange_cli import __version__
from lagrange_cli.emit.python import SOLVE
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
_FINGERPRINTS: dict[tuple[int, str, bool, str], tuple[Model, str]] = {}


@dataclass(frozen=True)
class Functions:
    """An imported module of a system's functions, and what it cost to get it."""

    module: ModuleType
    target: str
    path: Path
    kernels: ModuleType | None
    generate_seconds: float
    """Writing the source (0 when it was on disk or already imported)."""
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
    """A hash of everything the generated module depends on: the model's equations and
    monitored quantities (with the file's function definitions written out, as codegen writes
    them), the options, lagrange's and the compiler's versions, the code generator, the kernels.
    Remembered per model object (which it keeps alive, so that its id is not reused)."""
    model = model.with_definitions()
    memo = (id(model), target, jacobian, str(event))
    if memo in _FINGERPRINTS:
        return _FINGERPRINTS[memo][1]
    parts = [__version__, _generator_source(), target, str(jacobian), str(event), sys.version, _numba_version(target), _kernels_source() if target == "numba" else ""]
    parts += [str(model.coordinates), str([p.name for p in model.parameters]), str(model.mass_matrix), str(model.forcing)]
    parts += [str(model.energy), str(model.momenta), str(model.lagrangian), str(model.dissipation), str(model.generalized_forces)]
    parts += [str((c.expr, c.jacobian, c.bias, c.acceleration_bias, c.holonomic)) for c in model.constraints]
    key = hashlib.sha256("\x00".join(parts).encode()).hexdigest()[:20]
    _FINGERPRINTS[memo] = (model, key)
    return key


def build(model: Model, target: str, jacobian: bool = False, event: sp.Expr | None = None) -> Functions:
    """The system's functions for `target` ("numba" or "python"), generated only when not cached."""
    if target == "numba" and not numba_available():
        raise LagrangeError(f"the compiled path needs numba: {NUMBA_HINT}, or use `--backend python`")
    start = time.perf_counter()
    kernels = kernels_module() if target == "numba" else None
    key = fingerprint(model, target, jacobian, event)
    name = f"lagrange_{target}_{key}"
    path = cache_dir() / f"{name}.py"
    if name in _LOADED:
        return Functions(_LOADED[name], target, path, kernels, 0.0, 0.0, True)
    loaded = generated = time.perf_counter()
    reused = path.exists()
    if not reused:
        _write(path, module_source(model, target, jacobian, event, kernels))
        generated = time.perf_counter()
    module = _import(name, path)
    _LOADED[name] = module
    return Functions(module, target, path, kernels, generated - loaded, time.perf_counter() - generated + loaded - start, reused)


def kernels_module() -> ModuleType:
    """The compiled integration loops (kernels.py), imported from their copy in the cache."""
    text = _kernels_source()
    name = "lagrange_kernels_" + hashlib.sha256((text + _numba_version("numba") + sys.version).encode()).hexdigest()[:20]
    if name not in _LOADED:
        path = cache_dir() / f"{name}.py"
        if not path.exists():
            _write(path, text)
        _LOADED[name] = _import(name, path)
    return _LOADED[name]


def module_source(model: Model, target: str, jacobian: bool, event: sp.Expr | None, kernels: ModuleType | None = None) -> str:
    """The whole module: a header, the linear solver (the kernels' for numba), the system's functions."""
    header = f'"""{model.title}: numeric functions generated by lagrange {__version__} from {Path(model.source).name} ({target}). Do not edit."""\n\n'
    body = codegen.source(model, target, jacobian, event)
    if target == "numba":
        assert kernels is not None
        return header + f"from {kernels.__name__} import lu_solve as _lu_solve\n\n" + body + JIT_FOOTER
    imports = "import numpy\n\n\n" if jacobian else ""
    return header + imports + SOLVE + "\n\n\n" + body


@functools.cache
def _kernels_source() -> str:
    return resources.files("lagrange_cli.numeric").joinpath("kernels.py").read_text(encoding="utf-8")


@functools.cache
def _generator_source() -> str:
    """The code that writes the generated modules: a fix to it must not reuse modules cached before."""
    files = [("lagrange_cli.numeric", "codegen.py"), ("lagrange_cli.emit", "python.py"), ("lagrange_cli.emit", "common.py"), ("lagrange_cli", "algebra.py")]
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


def _write(path: Path, text: str) -> None:
    """Write atomically: concurrent runs see no file or the whole one."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_text(path, text)
    except OSError as error:
        raise LagrangeError(f"cannot write generated code to {path.parent} ({error.strerror}); set LAGRANGE_CACHE_DIR to a writable directory") from None


def _import(name: str, path: Path) -> ModuleType:
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise LagrangeError(f"cannot import the generated module {path}; delete {path.parent} and try again")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[name]
        raise
    return module
