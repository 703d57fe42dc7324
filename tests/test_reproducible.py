"""The settings `accuracy` and `stress` print repeat their runs exactly (issue 15, audit 3): the
symplectic step in full precision with its stages, rtol and atol as they read back, and a
`lagrange simulate` command line that gives the study's run bit for bit."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import numpy as np
import pytest
import typer.main
from typer.testing import CliRunner

from lagrange_cli import derive, spec
from lagrange_cli.cli import app
from lagrange_cli.numeric import accuracy, stress
from lagrange_cli.numeric.reports import simulate_command, simulate_options
from lagrange_cli.numeric.runs import Candidate, Point, atol_for, component_scale, exact_text, scaled_errors
from lagrange_cli.numeric.simulate import integrate

pytestmark = pytest.mark.usefixtures("private_cache")
runner = CliRunner()
FILE = "simple_pendulum"


@pytest.fixture(scope="module")
def model():  # type: ignore[no-untyped-def]
    return derive.derive(spec.load(spec.resolve(FILE)), shared=True)


@pytest.fixture(scope="module")
def study(model):  # type: ignore[no-untyped-def]
    return accuracy.study(model, candidates=[Candidate("symplectic"), Candidate("DOP853")], tolerances=[1e-4, 1e-6], t_end=3.0, samples=101, repeats=0)


def symplectic(points: tuple[Point, ...] | list[Point]) -> Point:
    found = [p for p in points if p.ok and p.ran is not None and p.ran.method == "symplectic"]
    assert found, [(p.method, p.status, p.reason) for p in points]
    return found[-1]


def parsed(command: str) -> dict[str, object]:
    """The options of a printed `lagrange simulate` command line, as the command's own parser reads them."""
    words = shlex.split(command)
    assert words[:2] == ["lagrange", "simulate"], words
    click_command = typer.main.get_command(app).commands["simulate"]  # type: ignore[attr-defined]
    context = click_command.make_context("simulate", words[2:], resilient_parsing=True)
    return dict(context.params)


def final_state(tmp_path: Path, command: str) -> tuple[np.ndarray, np.ndarray]:
    """(t, y) of the printed command, run in-process through the CLI."""
    out = tmp_path / "run.npz"
    result = runner.invoke(app, [*shlex.split(command)[1:], "-q", "-o", str(out)])
    assert result.exit_code == 0, result.output
    with np.load(out) as data:
        return data["t"], data["y"]


def test_exact_text_reads_back() -> None:
    for value in (1e-3, 1e-6, 1e-9, 2.5e-14, 0.0113, 0.011296182345678, 3.0, 1 / 3, 10.0**-7 * 1e-3):
        assert float(exact_text(value)) == value
    assert exact_text(1e-6) == "1e-06" and exact_text(20.0) == "20"


def test_a_study_atol_prints_as_written() -> None:
    """rtol x 1e-3 in floating point is 1.0000000000000002e-12 for 1e-9 (and 1.0000000000000001e-07 for 1e-4):
    the atol a study runs with is that product to 12 digits, which prints short and repeats the run."""
    assert 1e-9 * 1e-3 != 1e-12 and atol_for(1e-9) == 1e-12 and atol_for(1e-4) == 1e-7 and atol_for(2.5e-12) == 2.5e-15
    assert all(exact_text(atol_for(10.0**-k)) == f"1e-{k + 3:02d}" for k in range(3, 14))


def test_a_symplectic_setting_states_the_full_step_and_the_stages(study) -> None:  # type: ignore[no-untyped-def]
    p = symplectic(study.points)
    assert p.settings is not None and p.settings.stages in (2, 3)  # the pilot's choice
    match = re.fullmatch(r"step (\S+), (\d) stages", p.setting)
    assert match, p.setting
    assert float(match[1]) == p.settings.step and int(match[2]) == p.settings.stages
    options = simulate_options(p)
    assert options is not None and options[options.index("--step") + 1] == match[1] and options[options.index("--stages") + 1] == match[2]
    adaptive = next(q for q in study.points if q.ok and q.ran is not None and q.ran.method == "DOP853")
    assert adaptive.settings is not None
    match = re.fullmatch(r"rtol (\S+), atol (\S+)", adaptive.setting)
    assert match and float(match[1]) == adaptive.settings.rtol and float(match[2]) == adaptive.settings.atol


def test_the_printed_command_parses_back_to_the_study_settings(study, model) -> None:  # type: ignore[no-untyped-def]
    for p in study.points:
        if not p.ok:
            continue
        command = simulate_command(FILE, model, p)
        assert command is not None and p.settings is not None and p.ran is not None
        params = parsed(command)
        s = p.settings
        assert params["file"] == FILE and params["t_end"] == s.t_end and params["samples"] == len(s.t_eval)
        assert params["method"] == p.ran.method and params["backend"] == p.ran.backend
        if p.ran.method == "symplectic":
            assert params["step"] == s.step and params["stages"] == s.stages
        else:
            assert params["rtol"] == s.rtol and params["atol"] == s.atol and params["step"] is None


def test_the_printed_symplectic_setting_repeats_the_study_run_bit_for_bit(study, model, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """The audit's defect: `--step 0.0113` without the pilot's 3 stages gave 8.3e-4 for a reported 6.2e-7."""
    p = symplectic(study.points)
    command = simulate_command(FILE, model, p)
    assert command is not None and "--stages" in command
    t, y = final_state(tmp_path, command)
    reference = study.reference
    assert np.array_equal(t, np.asarray(reference.t))
    e = scaled_errors(y, np.asarray(reference.y), component_scale(np.asarray(reference.y)))
    assert float(e[-1]) == p.final_error and float(np.max(e)) == p.max_error
    assert p.settings is not None
    assert np.array_equal(y[-1], integrate(model, p.settings).y_last)


def test_a_stress_recommendation_repeats_its_run(model, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    report = stress.stress(model, candidates=[Candidate("symplectic")], t_end=2.0, long_factor=2.0, energy_factor=2.0, target=1e-5)
    outcome = report.outcomes[-1]  # high energy: the start differs from the file's
    best = outcome.recommended
    assert best is not None and best.settings is not None and best.ran is not None and best.ran.method == "symplectic"
    command = simulate_command(FILE, model, best)
    assert command is not None and "--initial" in command and "--stages" in command
    _, y = final_state(tmp_path, command)
    assert np.array_equal(y[-1], integrate(model, best.settings).y_last)
    document = stress.json_text(report)
    assert '"--step",\n' in document and f'"{exact_text(best.settings.step)}"' in document


def test_the_cli_prints_the_command(tmp_path: Path) -> None:
    result = runner.invoke(app, ["accuracy", FILE, "--method", "symplectic", "--tolerances", "1e-5", "--t-end", "1", "--samples", "51", "--repeats", "0", "-q"])
    assert result.exit_code == 0, result.output
    line = next(line for line in result.output.splitlines() if "try: lagrange simulate" in line)
    params = parsed(line.split("try: ", 1)[1])
    assert params["method"] == "symplectic" and params["stages"] in (1, 2, 3) and isinstance(params["step"], float)


def test_sweep_takes_the_stages() -> None:
    """`sweep --stages` reaches the symplectic runs: order 6 against order 2 at the same step."""
    errors = {}
    for stages in (1, 3):
        result = runner.invoke(app, ["sweep", FILE, "--method", "symplectic", "--step", "0.1", "--stages", str(stages), "--initial", "theta=0.5..1:2", "--measure", "energy_error", "-q"])
        assert result.exit_code == 0, result.output
        rows = [line.split(",") for line in result.stdout.splitlines() if line[:2] in ("0,", "1,")]
        errors[stages] = max(float(row[-1]) for row in rows)
    assert errors[3] < 1e-3 * errors[1], errors


def test_a_run_longer_than_simulates_budget_prints_the_budget_it_needs(study, model) -> None:  # type: ignore[no-untyped-def]
    """A study's budget (stress: 60 000 scipy steps, 100 x as many compiled) can exceed `simulate`'s default (20 000 and
    10^6): the printed command then gives `--max-steps`, so that it runs to the end as the study's run did."""
    from dataclasses import replace

    from lagrange_cli.numeric.integrators import MAX_STEPS

    point = next(p for p in study.points if p.ok and p.ran is not None and p.ran.method == "DOP853")
    assert "--max-steps" not in (simulate_options(point) or [])  # within the default: nothing to add
    longer = replace(point, steps=MAX_STEPS[point.ran.backend] + 1)
    command = simulate_command("simple_pendulum", model, longer)
    assert command is not None and parsed(command)["max_steps"] == 2 * (MAX_STEPS[point.ran.backend] + 1)


@pytest.mark.parametrize(("budget", "code"), [("5", 1), ("0", 2), ("x", 2)])
def test_simulate_max_steps_is_the_run_budget(budget: str, code: int) -> None:
    result = runner.invoke(app, ["simulate", FILE, "--method", "RK45", "--backend", "python", "--t-end", "10", "--max-steps", budget, "-q"])
    assert result.exit_code == code, result.output
    if code == 1:
        assert "stopped after 5 steps (the step budget)" in result.output and "--max-steps" in result.output, result.output
