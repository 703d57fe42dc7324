"""The Python API: a system file in, equations, analyses, runs and animations out, each result
showing itself in Jupyter.

    from lagrange_cli import load

    pendulum = load("double_pendulum")        # a bundled system, a path, or YAML text
    pendulum.equations                          # renders as LaTeX in a notebook
    pendulum.mass_matrix, pendulum.energy       # Formula objects (`.expr` is the sympy expression)
    pendulum.check()                            # the `expect` answers, as a table
    run = pendulum.simulate(t_end=5)            # a Trajectory
    run.states["theta"], run.to_dataframe()     # numpy arrays, a pandas DataFrame
    run.animate()                               # plays in the notebook; .save("motion.gif")

Every method calls the library functions the command line calls (`spec.load`, `derive.derive`,
`check.check`, `analysis`, `report`, `numeric.simulate`, `numeric.accuracy.study`,
`numeric.stress.stress`, the emitters, `animate`), so results and error messages are the same:
bad input raises `LagrangeError` (a `SpecError` for a bad file, with `file:line:col`), never
anything else on purpose. Nothing here needs a call before another: every property of a
`System` computes what it needs (and keeps it).

File text (titles, names) is data in every rendering: escaped in HTML, and in LaTeX only ever
the names the LaTeX emitter builds from its allow-list of macros.
"""

from __future__ import annotations

import functools
import html
import importlib
import importlib.util
import io
import os
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import sympy as sp

from lagrange_cli.animate import Animation
from lagrange_cli.errors import LagrangeError
from lagrange_cli.model import Model
from lagrange_cli.spec import SystemSpec

if TYPE_CHECKING:
    import numpy as np

    from lagrange_cli.numeric.simulate import Trajectory as Run

__all__ = ["Animation", "CheckReport", "Equations", "Formula", "Formulas", "Plot", "Report", "System", "Trajectory", "from_file", "from_text", "load", "targets"]

TEXT_NAME = "<text>"
"""How messages name a system given as YAML text (`from_text` without a name)."""

EMITTERS = {"text": "text", "latex": "latex", "python": "python", "c": "c", "octave": "octave", "jax": "jax", "json": "jsonmodel"}
"""`System.to(target)`: each target and its module under `lagrange_cli.emit`."""


# --- loading ---------------------------------------------------------------------------------


def load(source: str | os.PathLike[str]) -> System:
    """A system from a bundled name, a file or YAML text, told apart like this:

    1. a `pathlib.Path` (any `os.PathLike`) is a file;
    2. a string with a line break is YAML text (a system file has at least `coordinates:` and
       usually more lines);
    3. any other string is a path or the name of a bundled system, as the command line reads its
       FILE argument (`double_pendulum`, `systems/kepler.yaml`); if there is no such file or
       bundled system but the string is one line of YAML map text (`{coordinates: [x], ...}`),
       it is read as text.

    `from_file` and `from_text` say which without guessing. Raises `SpecError` (a bad file,
    with file:line:column) or `LagrangeError` (no such file), with the command line's messages.
    """
    if isinstance(source, os.PathLike):
        return from_file(source)
    if not isinstance(source, str):
        raise LagrangeError(f"load() takes a bundled system's name, a path or YAML text, got {type(source).__name__}")
    if "\n" in source or "\r" in source:
        return from_text(source)
    from lagrange_cli import spec

    try:
        return from_file(spec.resolve(source))
    except LagrangeError:
        if source.lstrip().startswith("{") and "coordinates" in source:
            return from_text(source)
        raise


def from_file(path: str | os.PathLike[str]) -> System:
    """A system from a file, or a bundled system's name (messages call it `systems/<name>.yaml`)."""
    from lagrange_cli import spec

    return System(spec.load(spec.resolve(os.fspath(path))))


def from_text(text: str, name: str = TEXT_NAME) -> System:
    """A system from YAML text; messages name it `name` (default `<text>`)."""
    from lagrange_cli import spec

    return System(spec.parse(text, name))


def targets() -> list[str]:
    """The targets `System.to` can write here: text, latex and python always; c, octave, jax and
    json when their emitters are installed."""
    return [target for target, module in EMITTERS.items() if importlib.util.find_spec(f"lagrange_cli.emit.{module}") is not None]


# --- rendering helpers -----------------------------------------------------------------------


def _pre(text: str) -> str:
    return f"<pre>{html.escape(text)}</pre>"


def _math(tex: str) -> str:
    """An `align*` for Jupyter (MathJax) and pdflatex: the emitter's output without its comment lines."""
    return "".join(line + "\n" for line in tex.splitlines() if not line.lstrip().startswith("%"))


class Formula:
    """One derived expression (or matrix): `expr` is the sympy object, `str()` its text,
    `_repr_latex_` an `align*` with the LaTeX emitter's names (`\\dot{\\theta}`)."""

    def __init__(self, name: str, tex_name: str, expr: sp.Basic, model: Model, momenta: Sequence[sp.Symbol] = ()) -> None:
        self.name, self.expr, self._tex_name, self._model, self._momenta = name, expr, tex_name, model, tuple(momenta)

    def __str__(self) -> str:
        from lagrange_cli.emit.common import printable

        if isinstance(self.expr, sp.MatrixBase):
            rows = ["  [" + ", ".join(str(x) for x in self.expr.row(i)) + "]" for i in range(self.expr.rows)]
            return printable(f"{self.name} =\n" + "\n".join(rows))
        return printable(f"{self.name} = {self.expr}")

    def __repr__(self) -> str:
        return str(self)

    @property
    def latex(self) -> str:
        """The formula as a LaTeX `align*` (amsmath)."""
        from lagrange_cli.emit import layout
        from lagrange_cli.emit.latex import Row, align, names, room

        doprint = names(self._model, self._momenta).printer().doprint
        if isinstance(self.expr, sp.MatrixBase):
            return "\\begin{align*}\n" + f"{self._tex_name} &= {doprint(self.expr)}\n" + "\\end{align*}\n"
        return align([Row(self._tex_name, layout.pieces(self.expr, doprint, room([self._tex_name])))])

    def _repr_latex_(self) -> str:
        return _math(self.latex)


class Formulas(Mapping[str, Formula]):
    """Formulas by name (the momenta by coordinate), rendered as one `align*`."""

    def __init__(self, items: Mapping[str, Formula], title: str) -> None:
        self._items, self._title = dict(items), title

    def __getitem__(self, key: str) -> Formula:
        if key not in self._items:
            raise LagrangeError(f"'{key}' is not one of {', '.join(self._items)} ({self._title})")
        return self._items[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._items)

    def __len__(self) -> int:
        return len(self._items)

    def __str__(self) -> str:
        return "\n".join(str(f) for f in self._items.values())

    def __repr__(self) -> str:
        return str(self)

    @property
    def latex(self) -> str:
        first = next(iter(self._items.values()), None)
        if first is None:
            return ""
        from lagrange_cli.emit import layout
        from lagrange_cli.emit.latex import Row, align, names, room

        doprint = names(first._model, first._momenta).printer().doprint
        lhs = [f._tex_name for f in self._items.values()]
        return align([Row(f._tex_name, layout.pieces(f.expr, doprint, room(lhs))) for f in self._items.values()])

    def _repr_latex_(self) -> str:
        return _math(self.latex)


class Equations(Sequence[sp.Expr]):
    """The equations of motion in Lagrange form, one expression per coordinate (each `= 0`), then
    the kept constraints: what `lagrange derive` prints. `str()` is its text, `latex` its
    `align*`, `form("matrix")` and `form("solved")` the other forms."""

    def __init__(self, model: Model) -> None:
        self._model = model
        self._exprs = tuple(model.equations())

    def __getitem__(self, index: Any) -> Any:
        return self._exprs[index]

    def __len__(self) -> int:
        return len(self._exprs)

    def form(self, form: str = "lagrange", latex: bool = False) -> str:
        """The text (or LaTeX) of `derive --form FORM`: lagrange, matrix or solved."""
        if form not in ("lagrange", "matrix", "solved"):
            raise LagrangeError(f"unknown form '{form}'; choose one of lagrange, matrix, solved")
        from lagrange_cli.emit import latex as tex
        from lagrange_cli.emit import text

        return tex.emit(self._model, form) if latex else text.emit(self._model, form)

    def __str__(self) -> str:
        return self.form()

    def __repr__(self) -> str:
        return str(self)

    @property
    def latex(self) -> str:
        """The `derive --latex` fragment: an `align*` (amsmath), preceded by a comment line."""
        return self.form(latex=True)

    def _repr_latex_(self) -> str:
        return _math(self.latex)


@dataclass(frozen=True)
class Report:
    """A text report (what the command line prints), shown in Jupyter as preformatted HTML.
    `value` is the library's result object (a Linearization, a Study, ...)."""

    text: str
    value: Any = None
    json: str = ""

    def __str__(self) -> str:
        return self.text

    def __repr__(self) -> str:
        return self.text

    def _repr_html_(self) -> str:
        return _pre(self.text)


class CheckReport:
    """The verdicts of `check` on the file's `expect` answers: `passed`, `results` (one per
    entry), a table in Jupyter and the same JSON as `lagrange check --json`."""

    def __init__(self, report: Any) -> None:
        self.report = report

    @property
    def passed(self) -> bool:
        """True when every answer is right (a file without `expect` passes vacuously)."""
        return self.report.status in ("pass", "skip")

    @property
    def results(self) -> tuple[Any, ...]:
        return tuple(self.report.results)

    @property
    def json(self) -> str:
        from lagrange_cli import check

        return check.to_json([self.report])

    def __str__(self) -> str:
        from lagrange_cli.errors import printable

        lines = [f"{r.entry}: {'pass' if r.passed else 'FAIL'} ({r.method})" + (f": {r.detail}" if r.detail else "") for r in self.results]
        return printable(f"{self.report.path}: {self.report.status}\n" + "\n".join(lines))

    def __repr__(self) -> str:
        return str(self)

    def _repr_html_(self) -> str:
        rows = "".join(
            f"<tr><td>{html.escape(r.entry)}</td><td style='color:{'green' if r.passed else 'red'}'>{'pass' if r.passed else 'FAIL'}</td>"
            f"<td>{html.escape(r.method)}</td><td>{html.escape(r.detail)}</td></tr>"
            for r in self.results
        )
        head = f"<p><b>{html.escape(self.report.path)}</b>: {html.escape(self.report.status)}</p>"
        return head + f"<table><tr><th>entry</th><th>result</th><th>decided</th><th>detail</th></tr>{rows}</table>"


class Plot:
    """A matplotlib figure: PNG in Jupyter, `save(path)` for .png, .svg or .pdf."""

    def __init__(self, figure: Any) -> None:
        self.figure = figure

    def _repr_png_(self) -> bytes:
        buffer = io.BytesIO()
        self.figure.savefig(buffer, format="png", dpi=80)
        return buffer.getvalue()

    def save(self, path: str | os.PathLike[str]) -> None:
        from lagrange_cli.files import atomic_write
        from lagrange_cli.numeric import output

        target = Path(path)
        output.check_suffix(target, output.PLOT_SUFFIXES, "plot")
        atomic_write(target, lambda stream: self.figure.savefig(stream, format=target.suffix.lower().lstrip("."), dpi=120))


# --- the system ------------------------------------------------------------------------------


class System:
    """A loaded and derived system. `spec` is the validated file, `model` the derived equations;
    the properties and methods below compute from them in any order."""

    def __init__(self, spec: SystemSpec) -> None:
        from lagrange_cli import derive

        self.spec = spec
        self.model: Model = derive.derive(spec)

    def __repr__(self) -> str:
        from lagrange_cli.errors import printable

        return printable(f"<System {self.title!r} from {self.source}: coordinates {', '.join(self.coordinates)}>", keep="")

    def _repr_html_(self) -> str:
        return f"<p><b>{html.escape(self.title)}</b> ({html.escape(self.source)}): coordinates {html.escape(', '.join(self.coordinates))}</p>"

    @property
    def title(self) -> str:
        return self.model.title

    @property
    def source(self) -> str:
        """The file as messages name it (`systems/<name>.yaml` for a bundled one, `<text>` for text)."""
        return self.model.source

    @property
    def coordinates(self) -> tuple[str, ...]:
        """The generalized coordinates left after `eliminate`, in order."""
        return self.model.coordinates

    @property
    def parameters(self) -> dict[str, float | None]:
        """Each parameter's default value (None when the file gives none)."""
        return {p.name: p.value for p in self.model.parameters}

    # -- the equations ------------------------------------------------------------------------

    @functools.cached_property
    def equations(self) -> Equations:
        """The equations of motion (Lagrange form), as `lagrange derive` prints them."""
        return Equations(self.model)

    @functools.cached_property
    def mass_matrix(self) -> Formula:
        """M(q, t) of M q_ddot = F + A^T lambda."""
        return Formula("M", "M", self.model.mass_matrix, self.model)

    @functools.cached_property
    def forcing(self) -> Formula:
        """F(q, q_dot, t) of M q_ddot = F + A^T lambda (a column)."""
        return Formula("F", "F", self.model.forcing, self.model)

    @functools.cached_property
    def momenta(self) -> Formulas:
        """The generalized momenta p_q = dL/dq_dot, by coordinate."""
        symbols = self._momentum_symbols
        from lagrange_cli.emit.latex import names

        tex = names(self.model, symbols).symbols
        items = {c: Formula(f"p_{c}", tex[s], p, self.model, symbols) for c, s, p in zip(self.coordinates, symbols, self._info.momenta, strict=True)}
        return Formulas(items, "the coordinates")

    @functools.cached_property
    def energy(self) -> Formula:
        """The energy function h(q, q_dot, t) = sum p q_dot - L (in velocities, not momenta)."""
        return Formula("h", "h", self._info.energy, self.model)

    @functools.cached_property
    def hamiltonian(self) -> Formula:
        """H(q, p, t): the energy function in the momenta `p_<q>`, by the Legendre transform, as
        `lagrange info` gives it. Raises `LagrangeError` saying why where it cannot be written
        (a mass matrix that depends on velocities, is singular, or too large to invert
        symbolically); `energy` is then h(q, q_dot)."""
        info = self._info
        if info.hamiltonian is None:
            raise LagrangeError(f"{self.source}: no Hamiltonian: {info.hamiltonian_note}; `energy` gives the energy function h(q, q_dot)")
        from lagrange_cli.emit.common import tidy

        return Formula("H", "H", tidy(info.hamiltonian), self.model, self._momentum_symbols)

    @functools.cached_property
    def hamilton(self) -> Any:
        """Hamilton's equations (`lagrange_cli.hamilton.Hamilton`): H(q, p), q_dot = dH/dp and
        p_dot = -dH/dq + Q in the state (q, p_<q>), as `derive --form hamilton` writes them.
        Raises `LagrangeError` where they are not written (kept constraints, ...)."""
        from lagrange_cli.hamilton import hamilton

        return hamilton(self.model)

    @functools.cached_property
    def reduced(self) -> Any:
        """Maggi's equations (`lagrange_cli.reduced.Reduced`) for velocity constraints: the independent
        velocities, q_dot = C u + d and (C^T M C) u_dot = C^T (F - M e), as `derive --form reduced`
        writes them. Raises `LagrangeError` for a system without a velocity constraint."""
        from lagrange_cli.reduced import reduced

        return reduced(self.model)

    @functools.cached_property
    def constraint_forces(self) -> Any:
        """The force (and torque) of each kept constraint on each particle and body
        (`lagrange_cli.forces.Forces`: `.on(k)` gives (carrier, "force"/"torque") -> lambda_k's
        factor, `.status` whether it is exact); see docs/format.md, "Sign conventions"."""
        from lagrange_cli.forces import forces

        return forces(self.model)

    @functools.cached_property
    def routhian(self) -> Any:
        """Routh's reduction (`lagrange_cli.routh.Routh`): the Routhian R(q_rest, q_rest_dot; p_<c>)
        for the ignorable coordinates c, the ignorable velocities, the effective potential and the
        reduced system (`.reduced`, a model whose equilibria are the relative equilibria), as
        `lagrange info --routh` gives them. Raises `LagrangeError` where the reduction does not apply."""
        from lagrange_cli.routh import routh

        return routh(self.model)

    def noether(self, search: bool = False) -> dict[str, sp.Expr]:
        """The conserved Noether charges of the file's declared `symmetries` (name -> charge
        sum p delta q - h delta t - G, in q, q_dot and t), and with `search` also those of the
        built-in family that `lagrange info` searches (`translation_x`, `rotation_z`, ...,
        `time_translation`). Raises `SpecError` for a declared symmetry that is not one."""
        from lagrange_cli import noether

        charges = {c.name: c.charge for c in noether.declared(self.spec, self.model)}
        if search:
            charges.update({c.name: c.charge for c in noether.search(self.spec, self.model) if c.name not in charges})
        return charges

    @functools.cached_property
    def info(self) -> Report:
        """Degrees of freedom, momenta, ignorable coordinates, energy, Hamiltonian and Noether charges: `lagrange info`."""
        from lagrange_cli import report
        from lagrange_cli.noether import with_charges

        text = with_charges(self.spec, self.model, report.info_text(self.model, self._info))
        return Report(text, self._info, with_charges(self.spec, self.model, report.info_json(self.model, self._info), "json"))

    @functools.cached_property
    def _info(self) -> Any:
        from lagrange_cli import analysis

        return analysis.info(self.model)

    @property
    def _momentum_symbols(self) -> tuple[sp.Symbol, ...]:
        return tuple(self._info.momentum_symbols)

    def to(self, target: str, **settings: Any) -> str:
        """The equations written for `target`: text, latex or python (and c, octave, jax, json
        where those emitters are installed); `settings` go to the emitter (`form="matrix"` for
        text and latex, `form="hamilton"` for Hamilton's equations and `form="reduced"` for
        the reduced equations of velocity constraints (every target, as `derive --form`),
        `standalone=True` for latex, `numba=True` for python)."""
        module_name = EMITTERS.get(target)
        if module_name is None:
            raise LagrangeError(f"unknown target '{target}'; choose one of {', '.join(EMITTERS)}")
        written = {"hamilton": "hamiltonian", "reduced": "reduced"}.get(str(settings.get("form")))
        if written is not None:  # Hamilton's equations in (q, p), Maggi's in (q, u): `derive --form hamilton/reduced`
            hamiltonian = importlib.import_module(f"lagrange_cli.emit.{written}")
            rest = {k: v for k, v in settings.items() if k != "form"}
            writers = {"text": hamiltonian.text, "latex": hamiltonian.latex, "python": hamiltonian.python}
            from lagrange_cli.emit import c, jax, jsonmodel, octave

            if written == "reduced":
                writers |= {"c": c.emit_reduced, "octave": octave.emit_reduced, "jax": hamiltonian.jax, "json": jsonmodel.emit_reduced}
            else:
                writers |= {"c": c.emit_hamilton, "octave": octave.emit_hamilton, "jax": jax.emit_hamilton, "json": jsonmodel.emit_hamilton}
            if target not in writers:
                hamiltonian.refuse(target)
            try:
                return str(writers[target](self.model, **rest))
            except TypeError as error:
                raise LagrangeError(f"the '{target}' target does not take these settings with form='{settings['form']}': {', '.join(rest)} ({error})") from None
        try:
            module = importlib.import_module(f"lagrange_cli.emit.{module_name}")
        except ModuleNotFoundError as error:
            if error.name != f"lagrange_cli.emit.{module_name}":
                raise
            raise LagrangeError(f"the '{target}' target is not available in this installation (no lagrange_cli.emit.{module_name}); available: {', '.join(targets())}") from None
        try:
            return str(module.emit(self.model, **settings))
        except TypeError as error:
            raise LagrangeError(f"the '{target}' target does not take these settings: {', '.join(settings)} ({error})") from None

    # -- analyses -----------------------------------------------------------------------------

    def check(self) -> CheckReport:
        """Check the file's `expect` answers, as `lagrange check` does."""
        from lagrange_cli import check

        return CheckReport(check.FileReport(self.source, tuple(check.check(self.spec, self.model))))

    def equilibria(self, ranges: Mapping[str, tuple[float, float]] | None = None) -> Report:
        """Equilibrium points with their stability, as `lagrange equilibria` prints them;
        `ranges` bounds a numeric search, e.g. `{"theta": (-3.2, 3.2)}`. `value` is the
        `report.Equilibria` (points, linearizations, steady motions)."""
        from lagrange_cli import report

        bounds = {}
        for name, (low, high) in (ranges or {}).items():
            low, high = _number(low, f"the range of '{name}'"), _number(high, f"the range of '{name}'")
            if not low < high:
                raise LagrangeError(f"the range of '{name}' is empty: its low end must be below its high end")
            bounds[self._coordinate(name)] = (low, high)
        found = report.equilibria(self.model, bounds)
        return Report(report.equilibria_text(self.model, found), found, report.equilibria_json(self.model, found))

    def linearize(self, about: Mapping[str, Any] | None = None) -> Report:
        """The linearization about an equilibrium (`{"theta": 0, "phi": "pi"}`; unnamed
        coordinates 0; a value is a number, a constant expression such as `"pi/2"`, or an
        expression in the parameters such as `"L + g*m/k"`), as
        `lagrange linearize` prints it; `value` is the `analysis.Linearization`."""
        import json

        from lagrange_cli import analysis, report

        point = {self._coordinate(name): self._point_value(name, value) for name, value in (about or {}).items()}
        lin = analysis.linearize(self.model, point)
        return Report(report.linearization_text(self.model, lin), lin, json.dumps(report.linearization_json(self.model, lin), indent=2) + "\n")

    def _point_value(self, name: str, value: Any) -> sp.Expr:
        """A coordinate's value: a number, or text that may use the parameters (`"L + g*m/k"`)."""
        from lagrange_cli import analysis
        from lagrange_cli.errors import Span

        if isinstance(value, str):
            return analysis.point_value(self.model, name, value, Span(f"the value of '{name}'", 1, 1, value))
        return _exact(value, f"the value of '{name}'")

    def state_space(self, about: Mapping[str, Any] | None = None, lqr: tuple[Sequence[float] | None, Sequence[float] | None] | None = None) -> dict[str, Any]:
        """The state-space linearization dx/dt = A x + B du, y - y0 = C x + D du about an operating
        point (`about` names coordinates and inputs; others 0 and their default), as
        `lagrange linearize` gives it: numpy arrays `A`, `B`, `C`, `D`, the name lists `state`,
        `inputs`, `outputs`, `about`, `controllability_rank`, `symbolic` (sympy matrices or None)
        and, with `lqr=(Q diagonal, R diagonal)` (None for identities), the LQR gain `K`."""
        from lagrange_cli import statespace

        signals = {i.name for i in self.model.inputs}
        point, given = {}, {}
        for name, value in (about or {}).items():
            if name in signals:
                given[name] = _exact(value, f"the value of '{name}'")
            else:
                point[self._coordinate(name)] = self._point_value(name, value)
        ss = statespace.state_space(self.model, point, given)
        result: dict[str, Any] = {**ss.arrays(), "state": ss.state, "inputs": ss.inputs, "outputs": ss.outputs, "about": dict(ss.about)}
        result.update(controllability_rank=ss.controllability_rank, symbolic=dict(ss.symbolic), notes=ss.notes)
        if lqr is not None:
            import numpy as np

            result["K"] = np.array(statespace.lqr(ss, *lqr), dtype=float)
        return result

    def _coordinate(self, name: str) -> sp.Symbol:
        if name not in self.coordinates:
            raise LagrangeError(f"'{name}' is not a coordinate of {self.source}; choose one of {', '.join(self.coordinates)}")
        return self.model.q[self.coordinates.index(name)]

    # -- numbers ------------------------------------------------------------------------------

    def simulate(self, **settings: Any) -> Trajectory:
        """Integrate from the file's initial state, as `lagrange simulate` does. Settings (all
        optional): t_end, method, rtol, atol, step, samples, t_eval, parameters (dict), initial
        (dict of coordinates and velocities), until, backend, max_step, max_steps, inputs (dict
        input name -> expression text of t, the coordinates, velocities and parameters, as
        `simulate --input`; others at their defaults). A failed run is returned (`failed` is
        True, `message` says why), as the command keeps it."""
        from lagrange_cli import inputs
        from lagrange_cli.numeric.simulate import simulate

        signals = settings.pop("inputs", None) or {}
        model = inputs.substitute(self.model, inputs.signal_expressions(self.model, [(name, str(text), None, None) for name, text in signals.items()])) if signals else self.model
        return Trajectory(self, simulate(model, **settings))

    def sweep(
        self,
        *,
        parameters: Mapping[str, Any] | None = None,
        initial: Mapping[str, Any] | None = None,
        sample: int | None = None,
        seed: int = 0,
        measures: Sequence[str] = (),
        section: str | None = None,
        workers: int = 1,
        scheduler: str | None = None,
        batch: int = 64,
        **settings: Any,
    ) -> Any:
        """Many runs over a grid or a sample, as `lagrange sweep` does. `parameters` and `initial`
        map names to a value (fixed), `(lo, hi, count)` (a grid axis, linear), `(lo, hi, count, "log")`,
        or `(lo, hi)` / `(lo, hi, None, "log")` (a range for `sample` points drawn with `seed`).
        `measures`, `section`, `workers`, `scheduler` (a dask.distributed address) and `batch` as
        in the command; other settings as `simulate` (t_end, method, rtol, atol, samples, until, ...).
        Returns a pandas DataFrame when pandas is installed, else a `lagrange_cli.sweep.Table`
        (`columns`, `rows` in index order, `column(name)`); failed runs are rows with their reason."""
        import importlib.util

        from lagrange_cli import sweep as library
        from lagrange_cli.errors import LagrangeError

        axes: list[Any] = []
        fixed: dict[str, dict[str, float]] = {"set": {}, "initial": {}}
        for kind, given in (("set", parameters or {}), ("initial", initial or {})):
            for name, value in given.items():
                if isinstance(value, (tuple, list)):
                    if not 2 <= len(value) <= 4:
                        raise LagrangeError(f"{name}: expected a value, (lo, hi, count), (lo, hi, count, 'log') or (lo, hi), got {value!r}")
                    spacing = value[3] if len(value) == 4 else "linear"
                    if spacing not in ("linear", "log"):
                        raise LagrangeError(f"{name}: the spacing must be 'linear' or 'log', got {spacing!r}")
                    count = value[2] if len(value) >= 3 else None
                    axes.append(library.Axis(kind, name, float(value[0]), float(value[1]), count, spacing == "log"))
                else:
                    fixed[kind][name] = value
        table = library.sweep(
            self.model,
            axes,
            sample=sample,
            seed=seed,
            measures=measures,
            section=section,
            workers=workers,
            scheduler=scheduler,
            batch=batch,
            parameters=fixed["set"],
            initial=fixed["initial"],
            **settings,
        )
        table = library.sorted_table(table)
        return table.to_pandas() if importlib.util.find_spec("pandas") is not None else table

    def accuracy(self, **settings: Any) -> Report:
        """A work-precision study (`lagrange accuracy`): settings of `numeric.accuracy.study`
        (candidates as method names such as `"DOP853:python"`, tolerances, t_end, parameters,
        initial, samples, repeats, max_steps, time_limit). `value` is the `Study`."""
        from lagrange_cli.numeric import accuracy

        if "candidates" in settings and settings["candidates"] is not None:
            settings["candidates"] = [accuracy.parse_candidate(c) if isinstance(c, str) else c for c in settings["candidates"]]
        study = accuracy.study(self.model, **settings)
        return Report(_study_text(study), study, accuracy.json_text(study))

    def stress(self, **settings: Any) -> Report:
        """Hard regimes and a method for each (`lagrange stress`): settings of
        `numeric.stress.stress` (scales such as `[("k", (1e2, 1e4))]`, target, candidates,
        t_end, long_factor, energy_factor, max_steps, time_limit). `value` is the `Report`."""
        from lagrange_cli.numeric import accuracy, stress

        if "candidates" in settings and settings["candidates"] is not None:
            settings["candidates"] = [accuracy.parse_candidate(c) if isinstance(c, str) else c for c in settings["candidates"]]
        result = stress.stress(self.model, **settings)
        return Report(_stress_text(result), result, stress.json_text(result))


def _number(value: Any, what: str) -> float:
    import math

    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise LagrangeError(f"{what} must be a finite number, got {value!r}")
    return float(value)


def _exact(value: Any, what: str) -> sp.Expr:
    """A number, or a constant expression given as text (`"pi/2"`), parsed by the safe parser."""
    if isinstance(value, str):
        from lagrange_cli.errors import Span
        from lagrange_cli.expr import Scope, parse_expression

        expr = parse_expression(value, Span(what, 1, 1, value), Scope({}, {}, sp.Symbol("t"), lambda e: e, what="numbers, pi, E and functions of them"))
        if not expr.is_number:
            raise LagrangeError(f"{what} must be a number, got {value!r}")
        return expr
    number = _number(value, what)
    return sp.Integer(int(number)) if isinstance(value, int) else sp.Float(number)


def _study_text(study: Any) -> str:
    from lagrange_cli.errors import printable

    lines = [f"{study.title}: work-precision study, t = 0 .. {study.t_end:.4g}", f"reference: {study.reference.description}"]
    lines += [f"  {note}" for note in study.notes]
    lines.append(f"{'method':<24} {'setting':<14} {'error':>9} {'seconds':>9} {'evals':>8} status")
    for p in study.points:
        error = max(p.final_error, p.rms_error)
        lines.append(f"{p.resolved:<24} {p.setting:<14} {error:9.2e} {p.seconds:9.3g} {p.nfev:8d} {p.status}" + (f": {p.reason}" if p.reason else ""))
    return printable("\n".join(lines)) + "\n"


def _stress_text(result: Any) -> str:
    from lagrange_cli.errors import printable

    lines = [f"{result.title}: stress at required error {result.accuracy:g}"]
    for outcome in result.outcomes:
        best = outcome.recommended
        lines.append(f"{outcome.regime.name}: " + ("; ".join(outcome.diagnosis.findings) or "benign") + (f"; recommended {best.resolved} at {best.setting}" if best else "; no method meets it"))
    return printable("\n".join(lines)) + "\n"


# --- trajectories ----------------------------------------------------------------------------


class Trajectory:
    """One run of a system: `times`, `states` (coordinates and velocities by name), `energy`,
    `status` and `message`, and `run`, the `numeric.simulate.Trajectory` (invariants, settings,
    step counts). `plot()` draws it, `animate()` moves the mechanism, `to_dataframe()` gives a
    pandas DataFrame."""

    def __init__(self, system: System, run: Run) -> None:
        self.system, self.run = system, run

    @property
    def times(self) -> np.ndarray:
        return self.run.t

    @property
    def states(self) -> dict[str, np.ndarray]:
        """Each coordinate and velocity (`theta`, `theta_dot`) at the sample times."""
        return {name: self.run.y[:, i] for i, name in enumerate(self.run.names)}

    @property
    def energy(self) -> np.ndarray:
        """The energy function h at the sample times."""
        return self.run.energy

    @property
    def status(self) -> str:
        return self.run.status

    @property
    def message(self) -> str:
        return self.run.message

    @property
    def failed(self) -> bool:
        return self.run.failed

    def __repr__(self) -> str:
        from lagrange_cli.errors import printable

        return printable(f"<Trajectory of {self.run.title!r}: {len(self.times)} samples, {self.status}: {self.message}>", keep="")

    def _repr_html_(self) -> str:
        rows = "".join(
            f"<tr><td>{html.escape(i.name)}</td><td>{'conserved' if i.conserved else 'not conserved'}</td><td>{i.initial:.6g}</td><td>{i.max_change:.2e}</td><td>{i.relative:.2e}</td></tr>"
            for i in self.run.invariants
        )
        s = self.run.settings
        head = f"<p><b>{html.escape(self.run.title)}</b>: {html.escape(s.method)} ({html.escape(s.backend)}), {len(self.times)} samples; {html.escape(self.status)}: {html.escape(self.message)}</p>"
        return head + (f"<table><tr><th>quantity</th><th>expected</th><th>initial</th><th>max change</th><th>relative</th></tr>{rows}</table>" if rows else "")

    def to_dataframe(self) -> Any:
        """A pandas DataFrame indexed by `t`, one column per coordinate and velocity, and `energy`.
        Needs pandas (`pip install pandas`); raises `LagrangeError` saying so otherwise."""
        try:
            import pandas
        except ImportError:
            raise LagrangeError("to_dataframe() needs pandas, which is not installed: `pip install pandas`") from None
        frame = pandas.DataFrame({**self.states, "energy": self.energy}, index=pandas.Index(self.times, name="t"))
        return frame

    def plot(self) -> Plot:
        """The figure of `lagrange simulate --plot`: coordinates against time, energy, phase portraits."""
        from lagrange_cli.numeric import output

        output.check_plot(Path("figure.png"))
        return Plot(output.simulation_figure(self.run, self.system.model))

    def animate(self, *, speed: float = 1.0, fps: float | None = None, view: str | None = None, trail: float | None = None, frames: int | None = None) -> Animation:
        """The mechanism moving (see `lagrange_cli.animate.animation`): plays in Jupyter
        (`_repr_html_`), `save("motion.gif" | ".mp4" | ".html")`, `frame(k)` for one PNG."""
        from lagrange_cli import animate

        return animate.animation(self.system.spec, self.system.model, self.run, speed=speed, fps=fps, view=view, trail=trail, frames=frames)
