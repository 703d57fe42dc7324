"""The stress test: regimes built as asked, stiffness and singular coordinates diagnosed, the
naive method's failure and the recommended method's success shown, and the CI exit code."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from lagrange_cli.cli import app
from lagrange_cli.errors import LagrangeError
from lagrange_cli.numeric import reference, stress
from lagrange_cli.numeric.accuracy import Candidate

from .conftest import ROOT
from .helpers import model_from, model_of

runner = CliRunner()
SCIPY = [Candidate("RK45", "python"), Candidate("Radau", "python"), Candidate("DOP853", "python")]


pytestmark = pytest.mark.usefixtures("private_cache")


def test_scales_parse_into_decades_and_lists() -> None:
    assert stress.parse_scale("k=1e2..1e4") == ("k", pytest.approx((1e2, 1e3, 1e4)))
    assert stress.parse_scale("k=1,5") == ("k", (1.0, 5.0))
    for bad in ("k", "k=a..b", "=1", "k=0..10"):
        with pytest.raises(LagrangeError, match="--scale"):
            stress.parse_scale(bad)


def test_default_regimes_include_long_high_energy_and_near_singular() -> None:
    model = model_from(ROOT / "systems" / "spherical_pendulum.yaml")
    names = [r.name for r in stress.regimes(model, [])]
    assert names[0] == "defaults" and names[1].startswith("long horizon") and names[2].startswith("high energy")
    assert any(n.startswith("near singular (theta = 0.01") for n in names)
    constrained = model_from(ROOT / "systems" / "pendulum_multiplier.yaml")
    high = next(r for r in stress.regimes(constrained, []) if r.name.startswith("high energy"))
    x, y = 0.8414709848078965, -0.5403023058681398
    assert abs(x * high.initial["x_dot"] + y * high.initial["y_dot"]) < 1e-12  # the velocity constraint holds
    with pytest.raises(LagrangeError, match="not a parameter"):
        stress.regimes(model, [("kk", [1.0])])


def test_stiff_damped_spring_shows_the_naive_method_losing_and_radau_winning() -> None:
    model = model_from(ROOT / "systems" / "stiff_spring_pendulum_damped.yaml")
    report = stress.stress(model, scales=[("k", [1e6])], target=1e-5, candidates=SCIPY, t_end=2.0)
    (outcome,) = report.outcomes
    assert report.passed and outcome.recommended is not None and outcome.recommended.candidate == Candidate("Radau", "python")
    assert any(f.startswith("stiff") for f in outcome.diagnosis.findings)
    assert any("explicit step count explodes" in f for f in outcome.diagnosis.findings)
    # judged by the largest error over the samples, Radau needs rtol 1e-5 here (71 steps) where RK45 needs 1e-4 (709)
    assert outcome.naive is not None and outcome.naive.steps > 5 * outcome.recommended.steps


@pytest.mark.parametrize(("name", "scale", "fast"), [("stiff_spring_pendulum", "g", True), ("spherical_coordinates_particle", "m", False), ("simple_pendulum", "g", False)])
def test_two_time_scales_only_where_a_fast_mode_turns_many_times(name: str, scale: str, fast: bool) -> None:
    """A slowest rate passing through 0 at a turning point is not a second time scale."""
    model = model_from(ROOT / "systems" / f"{name}.yaml")
    report = stress.stress(model, scales=[(scale, [next(p.value for p in model.parameters if p.name == scale)])], target=1e-4, candidates=[Candidate("DOP853", "python")])
    (outcome,) = report.outcomes
    assert any(f.startswith("two time scales") for f in outcome.diagnosis.findings) == fast, outcome.diagnosis.findings


def test_near_pole_passage_is_diagnosed_as_a_coordinate_singularity() -> None:
    model = model_from(ROOT / "systems" / "spherical_pendulum_near_pole.yaml")
    report = stress.stress(model, scales=[("g", [9.81])], target=1e-4, candidates=[Candidate("DOP853", "python")], t_end=3.0)
    (outcome,) = report.outcomes
    assert outcome.diagnosis.condition > 1e4
    assert any("coordinate singularity" in f for f in outcome.diagnosis.findings) or outcome.diagnosis.condition < 1e6


def test_unreachable_accuracy_exits_1_and_reachable_exits_0(tmp_path: Path) -> None:
    common = ["stress", "harmonic_oscillator", "--scale", "k=4", "--t-end", "2"]
    ok = runner.invoke(app, [*common, "--accuracy", "1e-4", "--method", "RK45:python", "--json", str(tmp_path / "r.json")])
    assert ok.exit_code == 0, ok.output
    document = json.loads((tmp_path / "r.json").read_text())
    assert document["passed"] and document["regimes"][0]["recommended"]["method"] == "RK45:python"
    starved = runner.invoke(app, [*common, "--accuracy", "1e-4", "--method", "RK45:python", "--max-steps", "5"])
    assert starved.exit_code == 1 and "no method meets" in starved.output and "over step budget" in starved.output


def test_a_time_limit_makes_a_regime_undecided_never_failed(tmp_path: Path) -> None:
    common = ["stress", "harmonic_oscillator", "--scale", "k=4", "--t-end", "2", "--method", "RK45:python", "--accuracy", "1e-4"]
    limited = runner.invoke(app, [*common, "--budget", "1e-9", "--json", str(tmp_path / "r.json")])
    assert limited.exit_code == 0, limited.output
    assert "undecided" in limited.output and "no regime failed" in limited.output
    document = json.loads((tmp_path / "r.json").read_text())
    assert document["verdict"] == "undecided" and document["passed"] is False and document["regimes"][0]["verdict"] == "undecided"
    assert document["regimes"][0]["runs"][0]["status"] == "undecided"


def test_the_verdict_does_not_depend_on_the_clock(monkeypatch: pytest.MonkeyPatch) -> None:
    """The same stress test under a clock that jumps by an hour at every reading (a machine loaded
    beyond measure): the same verdicts, statuses, step counts and exit codes."""
    import time

    def outcome(args: list[str]) -> tuple[int, object]:
        result = runner.invoke(app, ["stress", "harmonic_oscillator", "--scale", "k=4,400", "--t-end", "2", "--method", "RK45:python,DOP853:python", "--json", "-", *args])
        document = json.loads(result.stdout)
        runs = [[(p["method"], p["setting"], p["status"], p["steps"]) for p in r["runs"]] for r in document["regimes"]]
        return result.exit_code, (document["verdict"], [r["verdict"] for r in document["regimes"]], runs)

    cases = (["--accuracy", "1e-5"], ["--accuracy", "1e-5", "--max-steps", "40"])
    quiet = [outcome(args) for args in cases]
    real = time.perf_counter
    jumps = iter(range(10**9))
    monkeypatch.setattr(time, "perf_counter", lambda: real() + 3600.0 * next(jumps))
    loaded = [outcome(args) for args in cases]
    assert loaded == quiet
    assert quiet[0][0] == 0 and quiet[1][0] == 1  # both verdicts occur: the comparison can fail


@pytest.mark.parametrize(("args", "text"), [(["--scale", "q=1..10"], "not a parameter"), (["--accuracy", "2"], "--accuracy"), (["--method", "Euler"], "unknown method")])
def test_stress_bad_options_exit_2(args: list[str], text: str) -> None:
    result = runner.invoke(app, ["stress", "harmonic_oscillator", *args])
    assert result.exit_code == 2 and text in result.output and "Traceback" not in result.output


def test_spectrum_does_not_count_a_saddle_pair_as_stiffness() -> None:
    from lagrange_cli.numeric import diagnostics

    saddle = diagnostics.spectrum(np.array([[0.0, 1.0], [1e6, 0.0]]))  # eigenvalues +-1000: an unstable pair
    assert saddle is not None and saddle.decay == 0 and saddle.growth == pytest.approx(1000)
    assert diagnostics.choose(saddle, 10.0)[0] == "DOP853"
    jacobian = np.zeros((4, 4))
    jacobian[:2, :2] = [[0.0, 1.0], [-1.0, 0.0]]  # a slow swing, +-i
    jacobian[2:, 2:] = [[0.0, 1.0], [-1e8, -2e4]]  # a critically damped fast mode, a double root at -1e4
    damped = diagnostics.spectrum(jacobian)
    assert damped is not None and damped.decay == pytest.approx(1e4, rel=1e-3) and damped.growth == 0 and damped.slowest == pytest.approx(1)
    assert diagnostics.choose(damped, 10.0)[0] == "Radau"
    assert diagnostics.choose(damped, 0.1)[0] == "DOP853"  # decay x t_end 1e3: stiff, but ~300 explicit steps are cheaper compiled
    assert diagnostics.choose(damped, 1.0, compiled=False)[0] == "Radau"


@pytest.mark.parametrize(
    ("name", "parameters", "initial", "picked"),
    [
        ("stiff_spring_pendulum", {}, {}, ("DOP853", "RK45")),
        ("stiff_spring_pendulum", {"k": 1e8}, {}, ("DOP853", "RK45")),
        ("heavy_top", {}, {}, ("DOP853", "RK45")),
        ("heavy_top", {}, {"theta": 0.01, "phi_dot": 0.0, "psi_dot": 0.0}, ("DOP853", "RK45")),
        ("double_pendulum", {}, {}, ("DOP853", "RK45")),
        ("double_pendulum_chaotic", {}, {}, ("DOP853", "RK45")),
        ("stiff_spring_pendulum_damped", {"k": 1e4}, {}, ("DOP853", "RK45")),
        (
            "stiff_spring_pendulum_damped",
            {"k": 1e8},
            {},
            ("DOP853", "RK45", "LSODA", "Radau"),
        ),  # a tie against LSODA (benchmarks/auto_bench.py); compiled Radau is 13x faster than DOP853 (benchmarks/radau_bench.py)
        ("stiff_spring_pendulum_damped", {"k": 1e10}, {}, ("Radau", "BDF", "LSODA")),
    ],
)
def test_auto_picks_explicit_unless_an_explicit_method_is_stability_limited_too_long(name: str, parameters: dict[str, float], initial: dict[str, float], picked: tuple[str, ...]) -> None:
    from lagrange_cli.numeric.policy import resolve

    settings = resolve(model_from(ROOT / "systems" / f"{name}.yaml"), method="auto", parameters=parameters, initial=initial, t_end=10.0)
    assert settings.method in picked, settings.notes


def test_report_names_the_naive_failure_and_the_recommended_success() -> None:
    # the damped stiff spring at k = 1e10: scipy's RK45 needs ~3e5 stability-limited steps
    # (~20 s in Python) for t = 0..10, Radau ~300 (~60 ms): above 2 x a budget of 5000 steps, the
    # naive run is not run at all (its stability-limited step count says so), and reported as over budget
    model = model_from(ROOT / "systems" / "stiff_spring_pendulum_damped.yaml")
    report = stress.stress(model, scales=[("k", [1e10])], target=1e-5, candidates=[Candidate("RK45", "python"), Candidate("auto")], max_steps=5000)
    outcome = report.outcomes[0]
    assert outcome.naive is not None and outcome.auto is not None
    assert outcome.naive.status == "over step budget" and outcome.naive.steps == 0 and "stability-limited" in outcome.naive.reason, outcome.naive
    assert any(f.startswith("RK45:python") and "not run: stiff" in f for f in outcome.diagnosis.findings), outcome.diagnosis.findings
    assert any(f.startswith("stiff:") for f in outcome.diagnosis.findings), outcome.diagnosis.findings
    assert outcome.recommended is not None and outcome.recommended.resolved.startswith(("Radau", "LSODA")) and outcome.auto.resolved.startswith(("Radau", "LSODA"))
    assert json.loads(stress.json_text(report))["regimes"][0]["naive"]["status"] == "over step budget"


def command_options(name: str) -> set[str]:
    """The long options of one command of the CLI."""
    import typer.main

    group = typer.main.get_command(app)
    command = group.commands[name]  # type: ignore[attr-defined]
    return {option for parameter in command.params for option in (*parameter.opts, *parameter.secondary_opts) if option.startswith("--")}


OPTION = r"(?<![\w-])--[a-z][a-z-]*[a-z]"


def test_every_option_the_numeric_messages_name_exists() -> None:
    """A hint names only options the CLI has (the numeric library's messages are shown by its commands)."""
    import re

    known = command_options("simulate") | command_options("accuracy") | command_options("stress")
    named = {option for path in (ROOT / "lagrange_cli" / "numeric").glob("*.py") for option in re.findall(OPTION, path.read_text())}
    assert named and named <= known, named - known


def test_stress_hints_name_only_stress_options(tmp_path: Path) -> None:
    """A reference run over its step budget: the hint must not suggest `--tolerances` (an
    `accuracy` option) to a user of `stress`."""
    import re

    report = tmp_path / "report.json"
    args = ["stress", "simple_pendulum", "--method", "RK45:python", "--max-steps", "1", "--t-end", "10000", "--json", str(report)]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    findings = [f for regime in json.loads(report.read_text())["regimes"] for f in regime["findings"]]
    assert any("reference run" in f for f in findings), findings
    named = {option for f in findings for option in re.findall(OPTION, f)}
    assert named and named <= command_options("stress"), named - command_options("stress")


# -- the audit's cases (tests/numeric_audit/) -------------------------------------------------------

AUDIT = ROOT / "tests" / "numeric_audit"


def independent(model: object, outcome: stress.Outcome, candidate: Candidate, rtol: float) -> float:
    """The recommended run's largest scaled error against a run of `candidate` at `rtol` that
    stress did not make (its own reference is Radau confirmed by LSODA)."""
    from lagrange_cli.numeric.runs import Setup, component_scale, run, scaled_errors

    recommended = outcome.recommended
    assert recommended is not None and recommended.candidate is not None
    setup = Setup(outcome.t_end, tuple(np.linspace(0.0, outcome.t_end, stress.SAMPLES).tolist()), dict(outcome.regime.parameters), dict(outcome.regime.initial))
    truth = run(model, candidate, rtol, setup, reference=True)  # type: ignore[arg-type]
    mine = run(model, recommended.candidate, recommended.tolerance, setup, reference=True)  # type: ignore[arg-type]
    assert not truth.failed and not mine.failed
    return float(np.max(scaled_errors(mine.y, truth.y, component_scale(truth.y))))


def test_a_stiff_spring_written_in_its_length_gets_an_implicit_reference_and_a_true_recommendation() -> None:
    """k = 1e10: an explicit reference at 2.5e-14 would take some 1e6 stability-limited steps per
    second, and scipy's implicit methods are round-off-limited below about 1e-8 here. The reference
    is Radau confirmed by LSODA, and the recommendation truly meets 1e-6 (checked against BDF)."""
    model = model_from(AUDIT / "stiff_elastic_pendulum_r.yaml")
    # max_steps 20000: the explicit reference attempt gives up after 10 x that many steps (not the default 2e6: minutes of CPU)
    report = stress.stress(model, scales=[("k", [1e10])], target=1e-6, candidates=[Candidate("Radau"), Candidate("DOP853")], t_end=0.2, max_steps=20_000)
    (outcome,) = report.outcomes
    assert "Radau" in outcome.reference and "implicit" in outcome.reference and outcome.reference_error < 1e-6
    assert not any(f.kind.startswith(("blow-up", "no reference")) for f in outcome.diagnosis.findings)
    assert report.passed and outcome.recommended is not None and outcome.recommended.method == "Radau"
    assert independent(model, outcome, Candidate("BDF"), 1e-8) <= 1e-6
    assert outcome.diagnosis.stiffness_ratio is not None and outcome.diagnosis.stiffness_ratio > 1e4


def test_the_damped_cart_gets_an_implicit_reference_and_a_true_recommendation() -> None:
    model = model_from(AUDIT / "damped_cart_pendulum.yaml")
    report = stress.stress(model, scales=[("c", [1e6])], target=1e-6, candidates=[Candidate("Radau"), Candidate("LSODA")], t_end=2.0)
    (outcome,) = report.outcomes
    assert report.passed and outcome.reference_error < 1e-7, outcome  # over 2 s the explicit reference is affordable (compiled); either way the verdict must be true
    assert not any(f.kind.startswith(("blow-up", "no reference")) for f in outcome.diagnosis.findings)
    assert independent(model, outcome, Candidate("BDF"), 1e-8) <= 1e-6


PLACEHOLDERS = ("nan", "rate 0/s", "stiffness ratio 1,", "cond M nan")


def test_a_reference_that_cannot_be_made_is_undecided_and_shows_no_placeholders() -> None:
    """A step budget too small for any reference: no false blow-up, the regime undecided (exit 0
    even with --accuracy), and what was measured is measured (along what the reference reached)."""
    result = runner.invoke(app, ["stress", "simple_pendulum", "--scale", "g=9.81", "--t-end", "1e5", "--accuracy", "1e-6", "--max-steps", "1", "--method", "Radau", "--json", "-"])
    assert result.exit_code == 0, result.output
    document = json.loads(result.stdout)
    (regime,) = document["regimes"]
    assert regime["verdict"] == "undecided" and document["verdict"] == "undecided" and "no reference" in regime["open_reason"]
    assert not any(f.startswith("blow-up") for f in regime["findings"]) and any(f.startswith("no reference") for f in regime["findings"])
    text = runner.invoke(app, ["stress", "simple_pendulum", "--scale", "g=9.81", "--t-end", "1e5", "--max-steps", "1", "--method", "Radau"]).output
    flat = " ".join(text.split())
    assert "undecided" in flat and not any(p in flat for p in PLACEHOLDERS), flat
    assert "along the reference run up to t = " in flat or "at the initial state only" in flat


def test_a_blow_up_both_reference_methods_confirm_is_a_failure_with_no_placeholders(tmp_path: Path) -> None:
    path = tmp_path / "blow_up.yaml"
    path.write_text("title: Blow-up\ncoordinates: [x]\nparameters: {}\nparticles:\n  p: {mass: 1, position: [x]}\npotential: -x**4\ninitial: {x: 1.0}\nsimulate: {t_end: 2}\n")
    result = runner.invoke(app, ["stress", str(path), "--t-end", "2", "--accuracy", "1e-6", "--method", "Radau", "--long", "1.5"])
    flat = " ".join(result.output.split())
    assert result.exit_code == 1, flat
    assert "blow-up (both reference methods stop there)" in flat and "Traceback" not in flat
    assert not any(p in flat for p in PLACEHOLDERS), flat


def test_cond_m_is_sampled_along_the_dense_output_near_a_pole_and_a_change_of_coordinates_is_suggested() -> None:
    """The near-pole spherical pendulum passes theta ~ 0.0074 between samples: the samples alone see
    a fraction of the peak cond M, the dense resampling finds it, and the finding names the
    coordinate and the change to make."""
    from lagrange_cli.numeric import diagnostics
    from lagrange_cli.numeric.reference import computed_reference, dense
    from lagrange_cli.numeric.runs import Setup, starting

    model = model_from(ROOT / "systems" / "spherical_pendulum_near_pole.yaml").with_definitions()
    setup = starting(model, Setup(3.0, tuple(np.linspace(0.0, 3.0, 31).tolist())))
    reference = computed_reference(model, setup, 1e-12)
    condition = diagnostics.mass_condition(model, setup.start.values, setup.start.y0)  # type: ignore[union-attr]
    sparse = diagnostics.condition_peak(condition, reference.t, reference.y)
    found = diagnostics.condition_peak(condition, reference.t, reference.y, dense(model, reference))
    assert sparse is not None and found is not None and found.reruns > 0
    assert found.condition > 4 * sparse.condition and found.condition == pytest.approx(1 / np.sin(0.007415) ** 2, rel=0.02)  # the true peak at theta_min
    report = stress.stress(model, scales=[("g", [9.81])], target=1e-4, candidates=[Candidate("DOP853")], t_end=3.0)
    (outcome,) = report.outcomes
    assert outcome.diagnosis.condition is not None and outcome.diagnosis.condition >= 0.9 * found.condition
    # closer to the pole (theta = 1e-4: cond M 1e8), the finding names the coordinate and the change to make
    peak = diagnostics.Peak(1e8, 0.0, np.array([1e-4, 0.3, 0.0, 50.0]), 1, 0)
    finding = stress._singularity(model, setup.start, condition, peak)  # type: ignore[arg-type]
    assert finding.kind == "near a coordinate singularity"
    assert "coordinates singular at theta = 0" in finding.detail and "phi_dot" in finding.detail and "start away from theta = 0" in finding.detail, finding


def test_a_top_whose_axis_passes_the_vertical_gets_the_change_of_coordinates_suggested() -> None:
    """Euler angles through theta ~ 1e-4 (cond M ~ 1e8, found along the dense output): the finding
    names theta = 0, the lost direction phi_dot - psi_dot and what to do, and a method truly meets 1e-6."""
    model = model_from(AUDIT / "top_through_pole.yaml")
    report = stress.stress(model, scales=[("g", [9.81])], target=1e-6, candidates=[Candidate("DOP853")], t_end=0.1)
    (outcome,) = report.outcomes
    assert outcome.diagnosis.condition is not None and outcome.diagnosis.condition > 1e7
    advice = next(f for f in outcome.diagnosis.findings if f.kind == "near a coordinate singularity")
    assert "coordinates singular at theta = 0" in advice.detail and "phi_dot" in advice.detail and "psi_dot" in advice.detail and "start away from theta = 0" in advice.detail
    assert report.passed and outcome.recommended is not None and outcome.recommended.error + outcome.reference_error <= 1e-6


def test_a_reference_is_computed_once_per_model_and_setup(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """reference.prepare for the same (system, state, window, tolerance) twice - as stress's regimes
    and repeated studies ask - runs the reference runs once; another tolerance runs them again."""
    from lagrange_cli.numeric import reference
    from lagrange_cli.numeric.runs import Setup

    model = model_from(ROOT / "systems" / "double_pendulum.yaml")
    calls: list[float] = []
    real = reference.run

    def counted(*args, **kwargs):  # type: ignore[no-untyped-def]
        calls.append(args[2])
        return real(*args, **kwargs)

    monkeypatch.setattr(reference, "run", counted)
    setup = Setup(1.0, tuple(np.linspace(0.0, 1.0, 11).tolist()))
    first = reference.prepare(model, setup, 1e-10)
    ran = len(calls)
    assert ran >= 2  # the reference and its confirmation (and the horizon's runs)
    again = reference.prepare(model, Setup(1.0, tuple(np.linspace(0.0, 1.0, 11).tolist())), 1e-10)
    assert len(calls) == ran and again[1] is first[1]
    reference.prepare(model, setup, 1e-9)
    assert len(calls) > ran


def test_regimes_measure_errors_at_dense_samples_as_many_per_unit_time_in_the_long_horizon() -> None:
    model = model_from(ROOT / "systems" / "spherical_pendulum.yaml")
    planned = stress.regimes(model, [], long_factor=10.0)
    assert planned[0].samples == stress.SAMPLES >= 2001
    assert planned[1].samples == min(stress.MAX_SAMPLES, 10 * (stress.SAMPLES - 1) + 1)


def test_explicit_runs_a_stiff_system_keeps_at_its_stability_limit_are_not_run_past_their_budget() -> None:
    """The damped elastic pendulum in r at k = 1e10 (decay 1e5/s) over t = 100: scipy's RK45 needs
    about 3.3e6 stability-limited steps, far above a 60000-step budget; it used to run to the budget
    (twice: its ladder and its default tolerance). Counted in steps, not run."""
    from lagrange_cli.numeric.runs import PointStatus, Setup, starting
    from lagrange_cli.numeric.status import Failure

    model = model_from(ROOT / "tests" / "numeric_audit_pilot" / "stiff_elastic_pendulum_r.yaml")
    setup = starting(model, Setup(100.0, tuple(np.linspace(0.0, 100.0, 11).tolist()), max_steps=60_000))
    needed = reference.stable_steps(model, setup, "RK45")
    assert 1e6 < needed < 1e7, needed
    assert reference.stable_steps(model, setup, "Radau") == 0.0
    assert reference.stable_steps(model, setup, "DOP853") == pytest.approx(needed * 3 / 6)
    point = stress._capped(model, stress.NAIVE, 1e-3, setup, None, np.ones(4), None, None)  # type: ignore[arg-type]  # not run: no reference needed
    assert point.status == PointStatus.OVER_BUDGET and point.failure == Failure.BUDGET and point.steps == 0
    assert "stability-limited" in point.reason and "not run" in point.reason
    calm = model_from(ROOT / "tests" / "numeric_audit_pilot" / "double_pendulum_nonstiff.yaml")
    assert reference.stable_steps(calm, starting(calm, Setup(10.0, (0.0, 10.0))), "RK45") == 0.0


def test_an_explicit_reference_that_runs_out_of_budget_where_the_system_is_stiff_goes_implicit_at_once() -> None:
    """Where an explicit reference attempt stopped at a stiff state (the spring at rest, decay 1e5/s),
    looser explicit attempts would be stability-limited as well: `stiff_at` says so; not at a calm state."""
    from lagrange_cli.numeric.reference import stiff_at
    from lagrange_cli.numeric.runs import Setup, starting

    model = model_from(ROOT / "tests" / "numeric_audit_pilot" / "stiff_elastic_pendulum_r.yaml")
    setup = starting(model, Setup(10.0, (0.0, 10.0)))
    assert stiff_at(model, setup, 0.5, np.array([1.0, 0.4, 0.0, 0.1]))
    calm = model_from(ROOT / "tests" / "numeric_audit_pilot" / "double_pendulum_nonstiff.yaml")
    assert not stiff_at(calm, starting(calm, Setup(10.0, (0.0, 10.0))), 0.5, np.array([0.3, 0.2, 0.0, 0.1]))


def _point(method: str, backend: str, nfev: int, error: float, seconds: float = 1.0):  # type: ignore[no-untyped-def]
    from dataclasses import replace

    from lagrange_cli.numeric.runs import PointStatus, Ran, unrun

    candidate = Candidate(method, backend if method in ("RK45", "DOP853") else "auto")
    point = unrun(candidate, 1e-5)
    return replace(point, status=PointStatus.FINISHED, ran=Ran(method, backend), nfev=nfev, steps=nfev // 6, max_error=error, seconds=seconds, reason="")


def test_a_method_losing_on_the_same_backend_goes_no_tighter() -> None:
    """Once a run meets the accuracy, a method whose run on the same backend missed it with more than
    SAME_BACKEND_LOSING x that work is not run tighter (work maps to time closely on one backend);
    a scipy method after a compiled run met it, PYTHON_AFTER_COMPILED; otherwise the wider LOSING."""
    best = _point("RK45", "compiled", 2_000_000, 3e-8)
    dop = _point("DOP853", "compiled", 3_200_000, 1e-5)
    radau = _point("Radau", "python", 20_000, 5e-6)
    assert stress._losing(Candidate("DOP853", "compiled"), best, dop) == stress.SAME_BACKEND_LOSING["compiled"]
    assert stress._losing(Candidate("Radau", "python"), best, radau) == stress.PYTHON_AFTER_COMPILED
    assert stress._losing(Candidate("Radau", "python")) == stress.LOSING
    assert stress._losing(Candidate("Radau", "python"), _point("LSODA", "python", 6000, 7e-7), radau) == stress.SAME_BACKEND_LOSING["python"]
    assert stress._losing(stress.NAIVE) == stress.NAIVE_LOSING
    assert stress.SAME_BACKEND_LOSING["compiled"] * 2_000_000 < 3_200_000  # DOP853 here stops at rtol 1e-5


def test_a_lone_meeting_run_is_not_timed_again(monkeypatch: pytest.MonkeyPatch) -> None:
    """Timing again in turns only serves to compare runs that could decide the recommendation or
    tie with it: with one such run (or none meeting the accuracy) nothing is run again."""
    from lagrange_cli.numeric.runs import Setup

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("timed again")

    monkeypatch.setattr(stress, "retime", refuse)
    setup = Setup(1.0, (0.0, 1.0))
    lone = [_point("RK45", "compiled", 100, 1e-8, 1.0), _point("Radau", "python", 100, 1e-8, 5.0)]
    assert stress._retimed(None, lone, None, setup, 1e-6, 0.0)[0] == lone  # type: ignore[arg-type]
    missing = [_point("RK45", "compiled", 100, 1e-3, 1.0), _point("DOP853", "compiled", 100, 1e-3, 1.05)]
    assert stress._retimed(None, missing, None, setup, 1e-6, 0.0)[0] == missing  # type: ignore[arg-type]


def test_only_meeting_runs_are_timed_again_and_one_run_under_two_names_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """auto resolved to DOP853 at rtol 1e-10 and DOP853's own run at 1e-10 are one run: timed again once, the time
    given to both; a run that misses the accuracy (RK45, 0.6 s against 0.9 s) can neither be recommended nor tie,
    so its first time stands; a second meeting run (Radau) is timed in turns with them."""
    from dataclasses import replace

    from lagrange_cli.numeric.runs import Setup
    from lagrange_cli.numeric.settings import validate

    model = model_from(ROOT / "systems" / "simple_pendulum.yaml")
    timed: list[list[str]] = []

    def retime(model: object, points: list, setup: object, repeats: int) -> list:  # type: ignore[type-arg]
        timed.append([p.ran.method for p in points])
        return [replace(p, seconds=p.seconds / 2, runs=repeats) for p in points]

    monkeypatch.setattr(stress, "retime", retime)
    dop = validate(model, method="DOP853", backend="compiled", rtol=1e-10, atol=1e-13)
    auto = replace(_point("DOP853", "compiled", 100, 3e-7, 0.9), candidate=stress.AUTO, settings=replace(dop, notes=("auto: picked",)))
    same = replace(_point("DOP853", "compiled", 100, 3e-7, 0.95), settings=dop)
    missing = replace(_point("RK45", "compiled", 100, 3e-6, 0.6), settings=validate(model, method="RK45", backend="compiled", rtol=1e-6, atol=1e-9))
    radau = replace(_point("Radau", "compiled", 100, 4e-7, 1.2), settings=validate(model, method="Radau", backend="compiled", rtol=1e-7, atol=1e-10))
    result, _ = stress._retimed(model, [missing, same, radau, auto], None, Setup(1.0, (0.0, 1.0)), 1e-6, 0.0)
    assert timed == [["DOP853", "Radau"]]  # the shared run once, in turns with Radau; not RK45
    assert result[0] == missing
    assert result[1].seconds == result[3].seconds == 0.475 and result[2].seconds == 0.6


def test_a_scipy_run_after_a_compiled_one_met_the_accuracy_gets_little_budget() -> None:
    """Once a compiled run meets the accuracy, scipy's runs (Python right-hand side, counted at
    COMPILED_STEPS x a compiled evaluation's work, where they cost 400-500 x as much) may spend only
    PYTHON_AFTER_COMPILED x its work: they cannot be the recommendation (the penalty pendulum of
    k = 1e9: 38 of 46 s went to scipy runs losing at 10-30 x). Counted in evaluations, never timed."""
    from lagrange_cli.numeric.runs import COMPILED_STEPS, Setup, capped_steps, work

    best = _point("DOP853", "compiled", 600_000, 8e-7)
    setup = Setup(5.0, (0.0, 5.0), max_steps=60_000)
    for candidate in (stress.NAIVE, Candidate("Radau", "python"), Candidate("LSODA"), Candidate("BDF")):
        assert stress._losing(candidate, best) == stress.PYTHON_AFTER_COMPILED
        cap = stress._cap(candidate, best, None, setup)
        assert cap == capped_steps(candidate, stress.PYTHON_AFTER_COMPILED * work(best), None, setup)
        assert cap <= 6_000  # 2 x 6000 scipy evaluations, 2-6 a step
    assert work(best) == 600_000 / COMPILED_STEPS
    # a compiled candidate, auto, or a scipy best keep the wider budgets
    assert stress._losing(Candidate("RK45", "compiled"), best) == stress.LOSING
    assert stress._losing(stress.AUTO, best) == stress.LOSING
    assert stress._losing(stress.NAIVE, _point("LSODA", "python", 6000, 7e-7)) == stress.NAIVE_LOSING


def test_a_tighter_run_predicted_past_its_cap_is_not_run() -> None:
    """A method's next rung is predicted from its last two finished runs (work ratio, counted, never
    timed): where that exceeds what it may spend once another run meets the accuracy, it is not run."""
    previous = _point("Radau", "python", 4_000, 5e-5)
    last = _point("Radau", "python", 8_000, 5e-6)
    assert stress.predicted_growth(previous, last) == 2.0
    assert stress.predicted_growth(None, last) == 1.0
    assert stress.predicted_growth(last, previous) == 1.0  # never below 1: a tighter run costs no less
    best = _point("DOP853", "compiled", 1_000_000, 8e-7)  # 10000 scipy evaluations' work
    cap = stress._losing(Candidate("Radau", "python"), best) * work_of(best)  # 2 x 10000
    assert work_of(last) * stress.predicted_growth(previous, last) < cap  # 16000: run
    steeper = _point("Radau", "python", 12_000, 5e-6)
    assert work_of(steeper) * stress.predicted_growth(previous, steeper) > cap  # 36000: not run


def work_of(point):  # type: ignore[no-untyped-def]
    from lagrange_cli.numeric.runs import work

    return work(point)


def test_scipy_runs_after_a_compiled_one_met_share_one_budget_over_their_ladder() -> None:
    """After a compiled run met the accuracy, a scipy method's whole ladder may spend
    PYTHON_AFTER_COMPILED x its work (counted): each rung gets what the earlier ones left."""
    from lagrange_cli.numeric.runs import Setup, work

    best = _point("DOP853", "compiled", 1_000_000, 8e-7)
    allowed = stress.PYTHON_AFTER_COMPILED * work(best)
    assert stress._remaining(Candidate("BDF"), best, 0.0) == allowed
    assert stress._remaining(Candidate("BDF"), best, 15_000.0) == allowed - 15_000.0
    setup = Setup(5.0, (0.0, 5.0), max_steps=60_000)
    assert stress._cap(Candidate("BDF"), best, None, setup, 15_000.0) < stress._cap(Candidate("BDF"), best, None, setup)
    assert stress._remaining(Candidate("RK45", "compiled"), best, 1e9) == stress.LOSING * work(best)  # compiled runs: per run, as before


def test_the_high_energy_start_meets_a_constraint_that_moves_in_time() -> None:
    """Audit 9 F1: with a kept constraint depending on t, x^2 + y^2 = l(t)^2, the velocities must meet
    a . v + b = 0 with b = -2 l l' (here 2 l(0) a w = 1.98), not a . v = 0: the high-energy regime's start was
    projected onto the latter, so it began at rest radially, off the constraint, and its verdict was about a
    state simulate calls inconsistent; and the file's free velocity (the swing) is 0, so the regime starts it from the
    slowest mode's rate like any file at rest."""
    model = model_of(
        """
title: a pendulum whose length is pumped by a kept constraint
coordinates: [x, y]
parameters: {m: {value: 0.7}, l0: {value: 1.2}, a: {value: 0.15}, w: {value: 5.5}, g: {value: 9.81}}
gravity: [0, -g]
particles: {bob: {mass: m, position: [x, y]}}
constraints: {string: x**2 + y**2 = (l0 + a*sin(w*t))**2}
initial: {x: 0.4673020107703806, y: -1.105273192803462, x_dot: 0.32127013240463664, y_dot: -0.7598753200523801}
"""
    )
    high = next(r for r in stress.regimes(model, []) if r.name.startswith("high energy"))
    x, y = 0.4673020107703806, -1.105273192803462
    v = np.array([high.initial["x_dot"], high.initial["y_dot"]])
    assert 2 * x * v[0] + 2 * y * v[1] == pytest.approx(2 * 1.2 * 0.15 * 5.5, rel=1e-12)  # d/dt (x^2 + y^2) = d/dt l^2 at t = 0
    tangential = (x * v[1] - y * v[0]) / np.hypot(x, y)
    assert high.name.startswith("high energy (at rest in the file")  # its free part, the swing, is 0 in the file
    assert abs(tangential) > 0.1  # so the swing is set from the slowest mode's rate, on top of l'(0) = a w radially


def test_a_high_energy_start_from_rest_on_a_kept_constraint_swings_along_it() -> None:
    """The Cartesian pendulum with a multiplier at rest at 2.5 rad (audit 3): the linearisation in (x, y) has a double
    zero rate across the rod, which forward differences turn into a spurious 2.7e-4/s mode; its high-energy regime got
    2.2e-5 m/s from it, the defaults again. Taken along the constraint (`policy.initial_spectrum`'s `tangent`), the
    slowest rate is the swing's 2.2/s, and the regime starts on the rod, moving along it at metres per second."""
    from lagrange_cli.numeric import policy
    from lagrange_cli.numeric.settings import validate

    model = model_from(ROOT / "tests" / "numeric_audit3" / "pendulum_multiplier_large_swing.yaml")
    base = validate(model, method="DOP853", backend="python")
    x, y = base.y0[0], base.y0[1]
    across = policy.initial_spectrum(model, base.values, base.y0)
    along = policy.initial_spectrum(model, base.values, base.y0, np.array([[-y], [x]]) / np.hypot(x, y))
    assert across is not None and along is not None
    assert across.slowest < 1e-3 * across.rate  # the spurious mode across the rod
    assert along.slowest == pytest.approx(along.rate, rel=1e-6) and along.rate == pytest.approx(across.rate, rel=1e-6)
    high = next(r for r in stress.regimes(model, []) if r.name.startswith("high energy"))
    assert "at rest in the file" in high.name and "slowest mode" in high.name, high.name
    v = np.array([high.initial["x_dot"], high.initial["y_dot"]])
    assert abs(x * v[0] + y * v[1]) <= 1e-12 * np.hypot(x, y) * np.linalg.norm(v)  # on the rod: d/dt (x^2 + y^2) = 0
    assert np.linalg.norm(v) > 3 * along.slowest  # 3 x the rate x the coordinates' sizes (at least 1 each)
