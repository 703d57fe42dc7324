"""The JSON target: valid against its published schema, every expression string read back by lagrange's
own parser into the model's expression, LaTeX strings that pdflatex compiles, and file text kept as data."""

from __future__ import annotations

import dataclasses
import inspect
import json
import random
import shutil
import subprocess
from pathlib import Path
from typing import Any

import pytest
import sympy as sp
from sympy.core.function import AppliedUndef

from lagrange_cli.emit import jsonmodel, latex
from lagrange_cli.errors import DerivationError, Span
from lagrange_cli.expr import SUPPORTED_FUNCTIONS, Scope, parse_expression
from lagrange_cli.model import Model

from .conftest import ROOT, SYSTEMS
from .helpers import model_from, model_of
from .limits import DEADLOCK
from .test_codegen_safety import HOSTILE, PENDULUM

jsonschema = pytest.importorskip("jsonschema")

SCHEMA = json.loads((ROOT / "docs" / "model.schema.json").read_text())
VALIDATOR = jsonschema.Draft202012Validator(SCHEMA)
PDFLATEX = shutil.which("pdflatex")
HOSTILE_FILES = sorted((ROOT / "tests" / "hostile").glob("title_*.yaml")) + sorted((ROOT / "tests" / "hostile").glob("name_*.yaml"))


def document(model: Model) -> dict[str, Any]:
    text = jsonmodel.emit(model)
    assert text.isascii() and text.endswith("}\n")
    data: dict[str, Any] = json.loads(text)
    return data


def test_the_schema_is_a_valid_draft_2020_12_schema() -> None:
    jsonschema.Draft202012Validator.check_schema(SCHEMA)
    assert SCHEMA["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    assert SCHEMA["properties"]["schema_version"]["const"] == jsonmodel.SCHEMA_VERSION


# -- reading a document back ------------------------------------------------------------------------


class Reader:
    """Parses the expression strings of a document with lagrange's parser, in the names the document declares."""

    def __init__(self, data: dict[str, Any]) -> None:
        self.time = sp.Symbol(data["time"]["name"])
        names = [c["name"] for c in data["coordinates"]] + [c["velocity"] for c in data["coordinates"]] + [p["name"] for p in data["parameters"]] + [i["name"] for i in data.get("inputs", [])]
        self.symbols = {name: sp.Symbol(name) for name in names}
        self.functions = {f["name"]: sp.Function(f["name"]) for f in data["functions"]}
        self.parameters = {p["name"]: sp.Symbol(p["name"]) for p in data["parameters"]}

    def scope(self, extra: dict[str, sp.Symbol] | None = None) -> Scope:
        def no_time_derivative(expr: sp.Expr) -> sp.Expr:
            raise AssertionError("a document's expression takes no total time derivative")

        symbols = {**self.symbols, **(extra or {})}
        return Scope(symbols, self.functions, self.time, no_time_derivative)

    def read(self, expression: dict[str, str], extra: dict[str, sp.Symbol] | None = None) -> sp.Expr:
        return parse_expression(expression["text"], Span("model.json", 1, 1), self.scope(extra))


def same(parsed: sp.Expr, original: sp.Expr) -> bool:
    return parsed == original or sp.simplify(parsed - original) == 0


@pytest.mark.parametrize("path", SYSTEMS, ids=lambda p: p.stem)
def test_every_bundled_system_is_valid_and_reads_back_into_the_same_model(path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    model = model_from(path)
    data = document(model)
    for limit in ("MAX_LENGTH", "MAX_NODES"):  # derived expressions (a rolling disk's F) may be longer than a file's own may be
        monkeypatch.setattr(f"lagrange_cli.expr.{limit}", 10**6)
    VALIDATOR.validate(data)
    reader = Reader(data)
    n = model.n
    assert [c["name"] for c in data["coordinates"]] == list(model.coordinates)
    assert [c["velocity"] for c in data["coordinates"]] == [str(v) for v in model.qd]
    assert [(p["name"], p["default"], p["real"], p["description"]) for p in data["parameters"]] == [(p.name, p.value, p.real, p.description) for p in model.parameters]
    pairs: list[tuple[dict[str, str], sp.Expr]] = [(data["mass_matrix"][i][j], model.mass_matrix[i, j]) for i in range(n) for j in range(n)]
    pairs += list(zip(data["forcing"], model.forcing, strict=True))
    pairs += list(zip(data["momenta"], model.momenta, strict=True)) + list(zip(data["generalized_forces"], model.generalized_forces, strict=True))
    pairs += [(data[key], getattr(model, key)) for key in ("energy", "lagrangian", "kinetic", "potential", "dissipation")]
    assert len(data["constraints"]) == len(model.constraints)
    for row, constraint in zip(data["constraints"], model.constraints, strict=True):
        assert (row["name"], row["multiplier"]["name"], row["holonomic"]) == (constraint.name, str(constraint.multiplier), constraint.holonomic)
        pairs += [(row["residual"], constraint.expr), (row["b"], constraint.bias), (row["c"], constraint.acceleration_bias)]
        pairs += list(zip(row["A"], constraint.jacobian, strict=True))
    pairs += [(item["expression"], expr) for item, (_, expr) in zip(data["eliminated"], model.eliminated, strict=True)]
    assert [(i["name"], i["default"], i["description"]) for i in data.get("inputs", [])] == [(i.name, i.value, i.description) for i in model.inputs]
    assert ("inputs" in data) == bool(model.inputs) and ("outputs" in data) == bool(model.outputs)
    assert [o["name"] for o in data.get("outputs", [])] == [name for name, _ in model.outputs]
    pairs += [(item["expression"], expr) for item, (_, expr) in zip(data.get("outputs", []), model.outputs, strict=True)]
    for expression, original in pairs:
        assert same(reader.read(expression), original), (expression["text"], original)
    for function in data["functions"]:
        if function["definition"] is not None:
            definition = model.definitions[function["name"]]
            arguments = {a: sp.Symbol(a) for a in function["arguments"]}
            assert same(reader.read(function["definition"], arguments), definition.expr)
    assert data["initial"]["q"] == [model.initial.get(c, 0.0) for c in model.coordinates]


def test_numbers_are_exact_and_derivatives_read_back() -> None:
    """Floats by repr (all 17 digits), rationals exact, a second derivative of a declared function."""
    x, k = sp.Symbol("x"), sp.Symbol("k")
    U = sp.Function("U")
    exprs = [sp.Float(0.1) * x + sp.Rational(1, 3) * k ** sp.Rational(3, 2), sp.Float(1.2345678901234567e-7) / x, sp.diff(U(x), x, 2) * sp.atan2(x, k) - sp.E ** (x * sp.pi)]
    exprs += [sp.sqrt(x) / sp.Abs(k) + sp.sign(x) * sp.cot(x) * sp.sec(k) * sp.csc(x), -(x**-3) + sp.Float(-2.5e300) * sp.acos(x) ** 2]
    scope = Scope({"x": x, "k": k}, {"U": U}, sp.Symbol("t"), lambda e: e)
    for expr in exprs:
        text = jsonmodel.text(expr)
        assert parse_expression(text, Span("x", 1, 1), scope) == expr, text
    assert "Derivative(Derivative(U(x), x)" not in jsonmodel.text(sp.diff(U(x), x, 2))


def test_the_functions_are_the_parsers() -> None:
    assert jsonmodel.FUNCTIONS == SUPPORTED_FUNCTIONS


def test_what_the_file_syntax_cannot_say_is_refused() -> None:
    x = sp.Symbol("x")
    for expr in (sp.I * x, sp.Piecewise((x, x > 0), (0, True)), sp.re(x)):
        with pytest.raises(DerivationError, match="system-file syntax"):
            jsonmodel.text(expr)


def test_output_is_deterministic_and_ordered() -> None:
    text = "coordinates: [b, a]\nparameters: {z: 2.0, y: 1.0}\nfunctions: [W, V]\nkinetic: z*b_dot**2/2 + y*a_dot**2/2\npotential: W(a) + V(b)\n"
    first, second = jsonmodel.emit(model_of(text)), jsonmodel.emit(model_of(text))
    assert first == second
    data = json.loads(first)
    assert [c["name"] for c in data["coordinates"]] == ["b", "a"]  # the file's order
    assert [p["name"] for p in data["parameters"]] == ["z", "y"]
    assert [f["name"] for f in data["functions"]] == ["V", "W"]  # sorted
    assert all(f["definition"] is None and f["arguments"] is None for f in data["functions"])


# -- LaTeX ---------------------------------------------------------------------------------------------


def latex_strings(value: Any) -> list[str]:
    if isinstance(value, dict):
        return [s for key, item in value.items() for s in ([item] if key.endswith("latex") and isinstance(item, str) else latex_strings(item))]
    if isinstance(value, list):
        return [s for item in value for s in latex_strings(item)]
    return []


def test_latex_strings_are_the_latex_emitters() -> None:
    model = model_from(ROOT / "systems" / "pendulum_multiplier.yaml")
    data = document(model)
    symbols = latex.names(model).symbols
    assert data["coordinates"][0]["velocity_latex"] == symbols[model.qd[0]]
    assert data["constraints"][0]["multiplier"]["latex"] == symbols[model.multipliers[0]] == r"\lambda_{\mathrm{rod}}"
    assert data["energy"]["latex"] == latex.names(model).printer().doprint(model.energy)


@pytest.mark.latex
@pytest.mark.skipif(PDFLATEX is None, reason="pdflatex not installed (make test installs it)")
def test_every_latex_string_compiles_in_pdflatex(tmp_path: Path) -> None:
    """All the LaTeX of every bundled system and of the hostile-name files, in one article."""
    strings: list[str] = []
    for path in [*SYSTEMS, *HOSTILE_FILES]:
        try:
            model = model_from(path)
        except Exception:  # a hostile file that is refused before it has a model
            assert path in HOSTILE_FILES
            continue
        strings += latex_strings(document(model))
    assert len(strings) > 500
    body = "\n".join(f"\\noindent$\\displaystyle {s}$\\par" for s in dict.fromkeys(strings))
    (tmp_path / "all.tex").write_text("\\documentclass{article}\n\\usepackage{amsmath}\n\\begin{document}\n" + body + "\n\\end{document}\n")
    result = subprocess.run([PDFLATEX, "-interaction=nonstopmode", "-halt-on-error", "all.tex"], cwd=tmp_path, capture_output=True, text=True, timeout=DEADLOCK)
    assert result.returncode == 0, result.stdout[-3000:]
    log = (tmp_path / "all.log").read_text(errors="replace")
    assert "\n! " not in log and "Undefined control sequence" not in log


# -- file text is data ---------------------------------------------------------------------------------


@pytest.mark.parametrize("text", HOSTILE, ids=range(len(HOSTILE)))
def test_hostile_text_stays_data_and_round_trips(text: str) -> None:
    model = dataclasses.replace(model_of(PENDULUM), title=text, description=text + "\n" + text, source=f"/some/dir/{text}.yaml")
    data = document(model)
    VALIDATOR.validate(data)
    assert data["title"] == text and data["description"] == text + "\n" + text and data["source"] == Path(f"/some/dir/{text}.yaml").name
    assert list(data) == SCHEMA["required"]  # nothing added, nothing lost


@pytest.mark.parametrize("path", HOSTILE_FILES, ids=lambda p: p.stem)
def test_hostile_files_give_valid_documents(path: Path) -> None:
    try:
        model = model_from(path)
    except Exception:  # refused by the reader: nothing to write
        return
    data = document(model)
    VALIDATOR.validate(data)
    assert data["title"] == model.title and data["description"] == model.description
    reader = Reader(data)
    rng = random.Random(1)
    point = {s: rng.uniform(0.5, 1.5) for s in reader.symbols.values()} | {reader.time: 0.3}
    for expression, original in zip(data["forcing"], model.forcing, strict=True):
        assert float(reader.read(expression).xreplace(point)) == pytest.approx(float(original.xreplace(point)), rel=1e-12)


def test_every_key_of_the_schema_is_documented() -> None:
    documentation = (ROOT / "docs" / "json.md").read_text()
    for key in [*SCHEMA["required"], *SCHEMA["properties"]]:
        assert f"`{key}`" in documentation, key


def test_inputs_and_outputs_read_back_and_evaluate_as_the_python_module(tmp_path: Path) -> None:
    """A file with inputs: the document lists them (name, default, description) and the outputs (name, expression);
    F and the outputs read back from the document equal the Python module's `forcing` and `outputs` at random
    states and random inputs. A file without them has neither key."""
    from lagrange_cli.emit import python

    from .helpers import load_module

    model = model_from(ROOT / "systems" / "quadrotor.yaml")
    data = document(model)
    VALIDATOR.validate(data)
    assert [i["name"] for i in data["inputs"]] == [i.name for i in model.inputs] and all(i["description"] for i in data["inputs"])
    reference = load_module(python.emit(model), tmp_path / "reference.py")
    reader = Reader(data)
    rng = random.Random(3)
    for _ in range(2):
        q = [rng.uniform(0.2, 1.3) for _ in model.q]
        qd = [rng.uniform(-1.0, 1.0) for _ in model.qd]
        u = {i.name: rng.uniform(-2.0, 2.0) for i in model.inputs}
        p = dict(reference.PARAMETERS)
        point = {sp.Symbol(k): v for k, v in (*zip(model.coordinates, q, strict=True), *zip(map(str, model.qd), qd, strict=True), *p.items(), *u.items())} | {reader.time: 0.0}
        got = [float(reader.read(e["expression"]).xreplace(point)) for e in data["outputs"]]
        assert got == pytest.approx([float(v) for v in reference.outputs(0.0, [*q, *qd], p, u)], rel=1e-12, abs=1e-12)
        forcing = [float(reader.read(e).xreplace(point)) for e in data["forcing"]]
        expected = reference.forcing(*([0.0] if "t" in inspect.signature(reference.forcing).parameters else []), q, qd, p, u)
        assert forcing == pytest.approx([float(v) for v in expected], rel=1e-10, abs=1e-12)
    plain = document(model_from(ROOT / "systems" / "double_pendulum.yaml"))
    assert "inputs" not in plain and "outputs" not in plain


# -- --form hamilton ------------------------------------------------------------------------------------


@pytest.mark.parametrize("path", SYSTEMS, ids=lambda p: p.stem)
def test_hamilton_documents_are_valid_and_read_back(path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`--to json --form hamilton`: valid against the schema, the model's keys as without the form, and the
    `hamilton` key's expressions read back into lagrange_cli.hamilton's (momenta declared as names); at a
    random state the rates in (q, q_dot) equal the symbolic route's rates in (q, p)."""
    from lagrange_cli.errors import LagrangeError
    from lagrange_cli.hamilton import hamilton, rates_in_velocities

    model = model_from(path)
    try:
        ham = hamilton(model)
    except LagrangeError:
        with pytest.raises(LagrangeError):
            jsonmodel.emit_hamilton(model)
        return
    text = jsonmodel.emit_hamilton(model)
    assert text.isascii()
    data = json.loads(text)
    VALIDATOR.validate(data)
    assert list(data)[-1] == "hamilton" and {k: v for k, v in data.items() if k != "hamilton"} == document(model)
    section = data["hamilton"]
    assert [m["name"] for m in section["momenta"]] == [str(p) for p in ham.p] and [m["rate"] for m in section["momenta"]] == [str(p) for p in ham.pd]
    assert section["route"] == ("symbolic" if ham.symbolic else "numeric")
    reader = Reader(data)
    momenta = {str(p): p for p in ham.p}
    for limit in ("MAX_LENGTH", "MAX_NODES"):  # the symbolic inverse of a full 3 x 3 M is bigger than a file's expression may be
        monkeypatch.setattr(f"lagrange_cli.expr.{limit}", 10**6)
    pairs = list(zip(section["bias"], ham.bias, strict=True)) + list(zip(section["rates"], rates_in_velocities(model), strict=True))
    if ham.symbolic:
        assert ham.hamiltonian is not None
        pairs += [(section["hamiltonian"], ham.hamiltonian), *zip(section["velocities"], ham.velocities, strict=True), *zip(section["momentum_rates"], ham.rates, strict=True)]
    else:
        assert section["hamiltonian"] is None and section["velocities"] is None and section["momentum_rates"] is None
    for expression, original in pairs:
        parsed = reader.read(expression, momenta)
        assert parsed == original or sp.expand(parsed - original) == 0 or _close(parsed, original), (expression["text"], original)
    undefined = any(e.atoms(AppliedUndef) for e in rates_in_velocities(model))
    if ham.symbolic and not undefined:  # (a function left undefined has no value at a point)
        rng = random.Random(4)
        point = {s: rng.uniform(0.5, 1.5) for s in [*model.q, *ham.p, *(p.symbol for p in model.parameters), *(i.symbol for i in model.inputs)]} | {model.t: 0.4}
        velocities = {v: float(e.xreplace(point)) for v, e in zip(model.qd, ham.velocities, strict=True)}
        for in_velocities, in_momenta in zip(section["rates"], section["momentum_rates"], strict=True):
            a = float(reader.read(in_velocities, momenta).xreplace(point | velocities))
            assert a == pytest.approx(float(reader.read(in_momenta, momenta).xreplace(point)), rel=1e-9, abs=1e-12)


def _close(parsed: sp.Expr, original: sp.Expr) -> bool:
    """Equal at a few random points (for expressions too big to simplify)."""
    rng = random.Random(9)
    symbols = sorted(original.free_symbols | parsed.free_symbols, key=str)
    for _ in range(3):
        point = {s: rng.uniform(0.5, 1.5) for s in symbols}
        if complex(parsed.xreplace(point)) != pytest.approx(complex(original.xreplace(point)), rel=1e-10, abs=1e-12):
            return False
    return True


def test_the_hamilton_key_is_documented() -> None:
    documentation = (ROOT / "docs" / "json.md").read_text()
    assert "`hamilton`" in documentation
    for key in SCHEMA["properties"]["hamilton"]["required"]:
        assert f"`{key}`" in documentation, key
