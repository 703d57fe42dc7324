"""One NAME=VALUE syntax for --set, --initial, --about, --range and --scale: repeated options and
comma lists alike, commas inside parentheses kept in the value, and clear exit-2 messages (the
option, the item, a caret) for a malformed item, an unknown name and a name given twice."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from lagrange_cli.cli import app
from lagrange_cli.cli.boundary import assignments
from lagrange_cli.cli.study import _scales
from lagrange_cli.errors import SpecError

pytestmark = pytest.mark.usefixtures("private_cache")
runner = CliRunner()


def invoke(*args: str) -> tuple[int, str, str]:
    result = runner.invoke(app, list(args))
    assert result.exception is None or isinstance(result.exception, SystemExit), result.exception
    return result.exit_code, result.stdout, result.stderr


def test_commas_split_items_only_outside_parentheses() -> None:
    items = assignments("--about", ["theta=atan2(1, 2), phi=Max(1,2)", "psi = pi/2"], "theta=0")
    assert [(i.name, i.value.strip()) for i in items] == [("theta", "atan2(1, 2)"), ("phi", "Max(1,2)"), ("psi", "pi/2")]
    assert items[1].text[items[1].value_start :].startswith("Max(1,2)")  # the caret's column


def test_scale_lists_continue_until_the_next_name() -> None:
    assert [(item.name, values) for item, values in _scales(["k=1,10,m=1..100", "c=2"])] == [("k", (1.0, 10.0)), ("m", (1.0, 10.0, 100.0)), ("c", (2.0,))]


@pytest.mark.parametrize(
    ("entries", "column", "text"),
    [
        (["g"], 1, "'g' is not an assignment: expected name=value"),
        (["g=1,l"], 5, "'l' is not an assignment"),
        (["g=1,,l=2"], 5, "an empty item"),
        (["g="], 1, "'g=' is not an assignment"),
        (["=1"], 1, "'=1' is not an assignment"),
        (["g=1", "l=2,g=3"], 5, "'g' is given twice in --set"),
    ],
)
def test_malformed_items_are_placed(entries: list[str], column: int, text: str) -> None:
    with pytest.raises(SpecError) as error:
        assignments("--set", entries, "g=1")
    first = str(error.value).splitlines()[0]
    assert first.startswith(f"--set:1:{column}: error: ") and text in first, str(error.value)
    caret = str(error.value).splitlines()[2]
    assert caret.index("^") - 4 == column - 1


@pytest.mark.parametrize(
    ("args", "separate"),
    [
        (["simulate", "double_pendulum", "--t-end", "0.1", "--samples", "3", "--backend", "python", "-o", "-", "--set", "g=9,l=2"], ["--set", "g=9", "--set", "l=2"]),
        (
            ["simulate", "double_pendulum", "--t-end", "0.1", "--samples", "3", "--backend", "python", "-o", "-", "--initial", "theta=0.5,phi_dot=atan2(1,2)"],
            ["--initial", "theta=0.5", "--initial", "phi_dot=atan2(1,2)"],
        ),
        (["linearize", "double_pendulum", "--about", "theta=0,phi=pi"], ["--about", "theta=0", "--about", "phi=pi"]),
        (["equilibria", "double_pendulum", "--range", "theta=-1..1,phi=-1..1"], ["--range", "theta=-1..1", "--range", "phi=-1..1"]),
    ],
)
def test_repeated_options_and_comma_lists_agree(args: list[str], separate: list[str]) -> None:
    option = args[-2]
    together = invoke(*args)
    apart = invoke(*args[:-2], *separate)
    assert together[0] == 0, together
    assert together[1] == apart[1]
    assert invoke(*args[:-2])[1] != together[1] or option in ("--range",)  # the values took effect


def test_about_keeps_commas_inside_parentheses() -> None:
    code, _, err = invoke("linearize", "double_pendulum", "--about", "theta=atan2(1,2),phi=0")
    assert code == 2 and "theta = atan(1/2), phi = 0 is not an equilibrium" in err, err


@pytest.mark.parametrize(
    ("args", "message", "hint"),
    [
        (["simulate", "double_pendulum", "--set", "g=1,ll=2"], "'ll' is not a parameter of", "did you mean 'l'?"),
        (["simulate", "double_pendulum", "--initial", "theta=1", "--initial", "phi_dt=2"], "'phi_dt' is not a coordinate or velocity of", "did you mean 'phi_dot'?"),
        (["accuracy", "harmonic_oscillator", "--set", "kk=1"], "'kk' is not a parameter of", "did you mean 'k'?"),
        (["linearize", "double_pendulum", "--about", "theta=0,ph=0"], "'ph' is not a coordinate of", "did you mean 'phi'?"),
        (["equilibria", "double_pendulum", "--range", "thetaa=-1..1"], "'thetaa' is not a coordinate of", "did you mean 'theta'?"),
        (["stress", "harmonic_oscillator", "--scale", "k=1,10,mm=1..10"], "'mm' is not a parameter of", "did you mean 'm'?"),
    ],
)
def test_unknown_names_say_what_is_known(args: list[str], message: str, hint: str) -> None:
    code, _, err = invoke(*args)
    option = next(a for a in reversed(args) if a.startswith("--"))
    lines = err.splitlines()
    assert code == 2 and lines[0].startswith(f"{option}:1:") and message in lines[0], err
    assert lines[0].endswith("systems/" + args[1] + ".yaml") and "site-packages" not in err
    assert "^" in lines[2] and hint in err


@pytest.mark.parametrize("option", ["--set", "--initial", "--about", "--range"])
def test_duplicates_are_refused(option: str) -> None:
    command, name, value = {"--set": ("simulate", "g", "1"), "--initial": ("simulate", "theta", "1"), "--about": ("linearize", "theta", "0"), "--range": ("equilibria", "theta", "-1..1")}[option]
    code, _, err = invoke(command, "double_pendulum", option, f"{name}={value}", option, f"{name}={value}")
    assert code == 2 and f"'{name}' is given twice in {option}" in err.splitlines()[0], err


# --- bundled systems are shown by a short name; the user's paths as written ----------------------


@pytest.fixture
def installed(tmp_path, monkeypatch: pytest.MonkeyPatch):
    """Bundled systems in a site-packages folder, as after `pip install`."""
    import shutil

    from lagrange_cli import spec

    from .conftest import ROOT

    folder = tmp_path / "lib" / "python3.11" / "site-packages" / "lagrange_cli" / "systems"
    folder.mkdir(parents=True)
    for name in ("double_pendulum", "kepler"):
        shutil.copy(ROOT / "systems" / f"{name}.yaml", folder)
    monkeypatch.setattr(spec, "bundled_systems", lambda: folder)
    return folder


@pytest.mark.parametrize(
    "args",
    [
        ["check", "double_pendulum"],
        ["check", "double_pendulum", "--json"],
        ["linearize", "double_pendulum", "--about", "theta=1"],
        ["simulate", "kepler", "--set", "kk=1"],
        ["accuracy", "kepler", "--set", "q=1"],
        ["stress", "kepler", "--scale", "q=1..10"],
    ],
)
def test_bundled_systems_are_shown_by_name(installed, args: list[str]) -> None:
    result = runner.invoke(app, args, env={"COLUMNS": "200"})
    assert "site-packages" not in result.output and str(installed) not in result.output, result.output
    assert f"systems/{args[1]}.yaml" in result.output, result.output


def test_check_names_bundled_systems_in_every_report(installed, tmp_path) -> None:
    junit = tmp_path / "report.xml"
    result = runner.invoke(app, ["check", "double_pendulum", "--junit", str(junit)])
    assert result.exit_code == 0 and "site-packages" not in junit.read_text() and "systems/double_pendulum.yaml" in junit.read_text()


def test_user_paths_are_shown_as_written(installed, tmp_path) -> None:
    path = tmp_path / "site-packages" / "mine.yaml"
    path.parent.mkdir()
    path.write_text((installed / "kepler.yaml").read_text())
    code, _, err = invoke("simulate", str(path), "--set", "kk=1")
    assert code == 2 and f"not a parameter of {path}" in err, err
    from lagrange_cli import spec

    assert spec.shown_name("systems/x.yaml") == "systems/x.yaml" and spec.shown_name(path) == str(path)
