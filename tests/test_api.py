"""The Python API: `load` tells its inputs apart, properties need no call order, results render
in Jupyter (LaTeX that compiles, HTML with file text escaped), errors are the command line's,
and docs/api.md names every public name."""

from __future__ import annotations

import inspect
import os
import re
import subprocess
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

import pytest
import sympy as sp
from typer.testing import CliRunner

import lagrange_cli
from lagrange_cli import api, load
from lagrange_cli.cli import app
from lagrange_cli.errors import LagrangeError, SpecError

from .conftest import ROOT
from .limits import DEADLOCK
from .test_latex import PDFLATEX, needs_pdflatex

pytestmark = pytest.mark.usefixtures("private_cache")
runner = CliRunner()
PENDULUM = "coordinates: [theta]\nparameters: {m: 1.0, l: 1.0, g: 9.81}\ngravity: [0, -g]\nparticles:\n  bob: {mass: m, position: [l*sin(theta), -l*cos(theta)]}\ninitial: {theta: 0.5}\n"


def test_import_and_load_stay_light() -> None:
    """`import lagrange_cli` loads no sympy; loading and deriving load no numpy or matplotlib."""
    code = (
        "import sys, lagrange_cli\nlight = 'sympy' not in sys.modules\nfrom lagrange_cli import load\nsystem = load('double_pendulum')\n"
        "system.equations._repr_latex_(); system.hamiltonian\nprint(light, *(name in sys.modules for name in ('numpy', 'matplotlib', 'scipy')))"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=DEADLOCK, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert result.stdout.split() == ["True", "False", "False", "False"], result.stderr


def test_load_tells_names_paths_and_text_apart(tmp_path: Path) -> None:
    path = tmp_path / "pendulum.yaml"
    path.write_text(PENDULUM)
    by_name, by_path, by_str_path, by_text = load("simple_pendulum"), load(path), load(str(path)), load(PENDULUM)
    assert by_name.source == "systems/simple_pendulum.yaml" and by_path.source == str(path) == by_str_path.source and by_text.source == "<text>"
    assert sp.simplify(by_path.equations[0] - by_text.equations[0]) == 0
    one_line = load("{coordinates: [x], particles: {p: {mass: 1, position: [x]}}}")
    assert one_line.coordinates == ("x",) and one_line.source == "<text>"
    assert api.from_text(PENDULUM, name="mine.yaml").source == "mine.yaml"
    with pytest.raises(LagrangeError, match="no such file: 'nothing_like_this', and no bundled system of that name"):
        load("nothing_like_this")
    with pytest.raises(LagrangeError, match="load\\(\\) takes a bundled system's name, a path or YAML text, got int"):
        load(3)  # type: ignore[arg-type]


def test_errors_are_the_command_lines(tmp_path: Path) -> None:
    """The same exception text the CLI prints (after its `error:` label, if any)."""
    bad = tmp_path / "bad.yaml"
    bad.write_text(PENDULUM.replace("sin(theta)", "sin(thetaa)"))
    with pytest.raises(SpecError) as caught:
        load(bad)
    cli = runner.invoke(app, ["derive", str(bad)])
    assert cli.exit_code == 2 and cli.stderr.strip() == str(caught.value).strip()
    assert str(caught.value).startswith(f"{bad}:5:35: error: unknown name 'thetaa'")
    with pytest.raises(LagrangeError) as off:
        load("double_pendulum").linearize({"theta": 1})
    cli = runner.invoke(app, ["linearize", "double_pendulum", "--about", "theta=1"])
    assert cli.exit_code == 2 and str(off.value) in cli.stderr
    with pytest.raises(LagrangeError, match=r"'psi' is not a coordinate of systems/double_pendulum\.yaml"):
        load("double_pendulum").linearize({"psi": 0})
    with pytest.raises(LagrangeError, match=r"'k' is not a parameter of systems/double_pendulum\.yaml"):
        load("double_pendulum").simulate(parameters={"k": 1.0})


def test_properties_need_no_call_order() -> None:
    """Each property read first on a fresh system gives what the model says."""
    for first in ("hamiltonian", "momenta", "energy", "forcing", "mass_matrix", "equations", "info"):
        system = load("double_pendulum")
        getattr(system, first)
    system = load("double_pendulum")
    model = system.model
    assert system.mass_matrix.expr == model.mass_matrix and system.forcing.expr == model.forcing
    assert tuple(system.equations) == model.equations() and len(system.equations) == 2
    assert sp.simplify(system.momenta["theta"].expr - model.momenta[0]) == 0
    assert sp.simplify(system.energy.expr - model.energy) == 0
    h = system.hamiltonian.expr  # H(q, p) at p = p(q, q_dot) is h(q, q_dot)
    at = {sp.Symbol("p_theta"): model.momenta[0], sp.Symbol("p_phi"): model.momenta[1]}
    point = {model.q[0]: 0.3, model.q[1]: -0.7, model.qd[0]: 1.1, model.qd[1]: 0.4, **{p.symbol: p.value for p in model.parameters}}
    assert float((h.xreplace(at) - model.energy).xreplace(point)) == pytest.approx(0.0, abs=1e-12)
    assert system.parameters == {"m": 1.0, "l": 1.0, "g": 9.81}


def test_no_hamiltonian_says_why() -> None:
    velocity = load("coordinates: [x]\nkinetic: x_dot**4/4 + x_dot**2/2\n")
    with pytest.raises(LagrangeError, match="no Hamiltonian: the Lagrangian is not quadratic in the velocities; `energy` gives the energy function h"):
        velocity.hamiltonian  # noqa: B018


@pytest.mark.latex
@needs_pdflatex
def test_repr_latex_compiles(tmp_path: Path) -> None:
    from .test_latex import compile_tex

    pieces = []
    for name in ("double_pendulum", "rolling_coin"):
        system = load(name)
        pieces += [system.equations._repr_latex_(), system.mass_matrix._repr_latex_(), system.forcing._repr_latex_(), system.momenta._repr_latex_(), system.energy._repr_latex_()]
    pieces.append(load("double_pendulum").hamiltonian._repr_latex_())
    for piece in pieces:
        assert piece.startswith("\\begin{align*}") and "%" not in piece
    assert PDFLATEX
    compile_tex(tmp_path, "api", "\\documentclass{article}\n\\usepackage{amsmath}\n\\begin{document}\n" + "\n".join(pieces) + "\\end{document}\n")


def test_html_reports_escape_file_text() -> None:
    hostile = "<img src=x onerror=alert(1)>"
    text = f"title: '{hostile}'\n" + PENDULUM + "expect:\n  momenta: {theta: 2*m*l**2*theta_dot}\n"
    system = api.from_text(text, name=f"{hostile}.yaml")
    verdict = system.check()
    assert not verdict.passed and len(verdict.results) == 1
    for page in (verdict._repr_html_(), system._repr_html_(), system.info._repr_html_()):
        assert "<img" not in page and "&lt;img src=x onerror=alert(1)&gt;" in page
    run = system.simulate(t_end=0.1, samples=3, backend="python")
    assert "<img" not in run._repr_html_() and "&lt;img" in run._repr_html_()
    assert '"status": "fail"' in verdict.json and "FAIL" in verdict._repr_html_()


def test_check_equilibria_and_linearize_match_the_cli() -> None:
    system = load("double_pendulum")
    assert system.check().passed
    found = system.equilibria()
    assert found.text == runner.invoke(app, ["equilibria", "double_pendulum"]).stdout
    assert len(found.value.points) == 4
    lin = system.linearize({"theta": 0, "phi": "pi"})
    assert lin.text == runner.invoke(app, ["linearize", "double_pendulum", "--about", "theta=0,phi=pi"]).stdout
    assert lin.value.stability == "unstable" and "<pre>" in lin._repr_html_()
    assert system.info.text == runner.invoke(app, ["info", "double_pendulum"]).stdout


def test_simulate_gives_a_trajectory_by_name() -> None:
    run = load("simple_pendulum").simulate(t_end=0.5, samples=6, backend="python")
    assert run.status == "finished" and not run.failed and list(run.times) == pytest.approx([0.0, 0.1, 0.2, 0.3, 0.4, 0.5])
    assert set(run.states) == {"theta", "theta_dot"} and run.states["theta"][0] == run.run.y[0, 0]
    assert len(run.energy) == 6 and "energy" in run._repr_html_()
    png = run.plot()._repr_png_()
    assert png.startswith(b"\x89PNG")


def test_to_dataframe_needs_pandas(monkeypatch: pytest.MonkeyPatch) -> None:
    run = load("simple_pendulum").simulate(t_end=0.2, samples=3, backend="python")
    monkeypatch.setitem(sys.modules, "pandas", None)  # type: ignore[arg-type]
    with pytest.raises(LagrangeError, match="to_dataframe\\(\\) needs pandas, which is not installed: `pip install pandas`"):
        run.to_dataframe()


def test_to_dataframe_with_pandas() -> None:
    pytest.importorskip("pandas")
    run = load("simple_pendulum").simulate(t_end=0.2, samples=3, backend="python")
    frame = run.to_dataframe()
    assert list(frame.columns) == ["theta", "theta_dot", "energy"] and frame.index.name == "t"


def test_to_writes_every_available_target(monkeypatch: pytest.MonkeyPatch) -> None:
    from lagrange_cli.emit import latex, python, text

    system = load("double_pendulum")
    assert system.to("text") == text.emit(system.model) and system.to("text", form="matrix") == text.emit(system.model, "matrix")
    assert system.to("latex", standalone=True) == latex.emit(system.model, standalone=True)
    assert system.to("python") == python.emit(system.model)
    assert {"text", "latex", "python"} <= set(api.targets())
    for target in api.targets():
        assert system.to(target).strip()
    with pytest.raises(LagrangeError, match="unknown target 'fortran'; choose one of text, latex, python, c, octave, jax, json"):
        system.to("fortran")
    monkeypatch.setitem(api.EMITTERS, "cobol", "cobol_not_written")
    with pytest.raises(LagrangeError, match="the 'cobol' target is not available in this installation"):
        system.to("cobol")


def public_names() -> set[str]:
    """Every name of the API: `api.__all__`, and each public attribute of its classes (not those
    inherited from collections.abc or object)."""
    names = set(api.__all__)
    inherited = {n for base in (Mapping, Sequence, object) for n in dir(base)}
    for name in api.__all__:
        value = getattr(api, name)
        if inspect.isclass(value):
            names |= {n for n in vars(value) if (not n.startswith("_") or n.startswith("_repr_")) and n not in inherited}
            names |= set(getattr(value, "__annotations__", {}))
    names |= {"spec", "model", "system", "run", "expr", "name", "text", "report", "figure"}  # instance attributes set in __init__
    return names


def test_docs_list_every_public_name() -> None:
    document = (ROOT / "docs" / "api.md").read_text()
    listed = set(re.findall(r"`([A-Za-z_][A-Za-z0-9_]*)", document))
    missing = sorted(public_names() - listed)
    assert not missing, f"docs/api.md does not mention: {', '.join(missing)}"
    assert set(lagrange_cli.API) == set(api.__all__)
    for name in lagrange_cli.API:
        assert getattr(lagrange_cli, name) is getattr(api, name)
