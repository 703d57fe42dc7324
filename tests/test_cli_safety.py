"""The command line's boundary (issue 11, classes 1 and 8): numeric options checked where they are
parsed, expression options explained with a caret, file text inert on the terminal (no rich
markup, no control characters), and a last-resort net that turns a bug into one line, exit 2."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import typer.main
from typer.testing import CliRunner

from lagrange_cli import cli
from lagrange_cli.cli import app
from lagrange_cli.errors import Diagnostic, Span, printable

from .conftest import ROOT

pytestmark = pytest.mark.usefixtures("private_cache")
runner = CliRunner()
PENDULUM = ROOT / "systems" / "simple_pendulum.yaml"
# Control characters (C0 but newline and tab, DEL, C1), lone surrogates and bidi controls: none may reach the terminal.
UNPRINTABLE = re.compile("[\x00-\x08\x0b-\x1f\x7f-\x9f\u061c\u200e\u200f\u2028\u2029\u202a-\u202e\u2066-\u2069\ud800-\udfff]")
HOSTILE = "\x1b[2J\x1b]0;pwned\x07\rpassed\b [bold]x[/bold] [/x] \u202e :smile: \x9b31m"
HOSTILE_YAML = '"\\e[2J\\e]0;pwned\\a\\rpassed\\b [bold]x[/bold] [/x] \\u202e :smile: \\x9b31m"'


def numeric_options() -> list[tuple[str, str, type]]:
    """Every int or float option of every command, read from the typer app (a new one joins by itself)."""
    group = typer.main.get_command(app)
    found = []
    for name, command in group.commands.items():  # type: ignore[attr-defined]
        for param in command.params:
            kind = param.type_descriptor.annotation
            if kind in (int, float) and param.opts[0].startswith("-"):
                found.append((name, max(param.opts, key=len), kind))
    return found


def output_options() -> list[tuple[str, str]]:
    group = typer.main.get_command(app)
    return [(name, max(p.opts, key=len)) for name, command in group.commands.items() for p in command.params if p.type_descriptor.annotation is Path]  # type: ignore[attr-defined]


def invoke(*args: str) -> tuple[int, str]:
    result = runner.invoke(app, list(args))
    assert "Traceback" not in result.output and "internal error" not in result.output, result.output
    assert result.exception is None or isinstance(result.exception, SystemExit), repr(result.exception)
    return result.exit_code, result.output


# --- option values -------------------------------------------------------------------------------


def test_the_numeric_options_are_all_found() -> None:
    names = {f"{command} {option}" for command, option, _ in numeric_options()}
    expected = {"simulate --t-end", "simulate --rtol", "simulate --atol", "simulate --step", "simulate --max-step", "simulate --samples"}
    expected |= {"accuracy --t-end", "accuracy --samples", "accuracy --repeats", "accuracy --budget", "stress --t-end", "stress --long", "stress --energy", "stress --budget", "stress --accuracy"}
    assert expected <= names


@pytest.mark.parametrize(("command", "option", "kind"), numeric_options(), ids=lambda v: v if isinstance(v, str) else "")
def test_every_numeric_option_refuses_nan_infinity_and_negative_values(command: str, option: str, kind: type) -> None:
    """Exit 2 before any work, naming the option and the allowed range."""
    for value in ["nan", "inf", "-inf", "-1", "1e400"] if kind is float else ["-1", "-1000000000", "9" * 400]:
        result = runner.invoke(app, [command, "simple_pendulum", option, value])
        assert result.exit_code == 2, (option, value, result.output)
        assert option in result.output and re.search(r"must be (a finite number|a number between|a whole number)", result.output), result.output
        assert "Traceback" not in result.output


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["simulate", "simple_pendulum", "--t-end", "0"], "--t-end"),
        (["simulate", "simple_pendulum", "--rtol", "1"], "--rtol"),
        (["simulate", "simple_pendulum", "--samples", "1"], "--samples"),
        (["simulate", "simple_pendulum", "--samples", "1000000000000"], "--samples"),
        (["accuracy", "simple_pendulum", "--repeats", "1000000"], "--repeats"),
        (["accuracy", "simple_pendulum", "--tolerances", "nan"], "--tolerances"),
        (["accuracy", "simple_pendulum", "--tolerances", "0..1e-3"], "--tolerances"),
        (["accuracy", "simple_pendulum", "--tolerances", "1e-3..inf"], "--tolerances"),
        (["accuracy", "simple_pendulum", "--tolerances", "-1e-3,1e-4"], "--tolerances"),
        (["accuracy", "simple_pendulum", "--tolerances", "1e-3..1e-300"], "--tolerances"),
        (["accuracy", "simple_pendulum", "--tolerances", ","], "--tolerances"),
        (["stress", "simple_pendulum", "--scale", "g=nan"], "--scale"),
        (["stress", "simple_pendulum", "--scale", "g=1,inf"], "--scale"),
        (["stress", "simple_pendulum", "--scale", "g=-1..10"], "--scale"),
        (["stress", "simple_pendulum", "--scale", "g=1..inf"], "--scale"),
        (["stress", "simple_pendulum", "--scale", "g=1e400..1"], "--scale"),
        (["stress", "simple_pendulum", "--scale", "g=1e-300..1e300"], "--scale"),
    ],
)
def test_ranges_and_lists_of_values_are_checked(args: list[str], message: str) -> None:
    code, output = invoke(*args)
    assert code == 2 and message in output


@pytest.mark.parametrize(
    ("args", "option"),
    [
        (["simulate", "simple_pendulum", "--until", "diff(theta, t)"], "--until"),
        (["simulate", "simple_pendulum", "--until", "Derivative(theta, t)"], "--until"),
        (["simulate", "simple_pendulum", "--until", "theta +"], "--until"),
        (["simulate", "simple_pendulum", "--until", ""], "--until"),
        (["simulate", "simple_pendulum", "--set", "g=1/"], "--set"),
        (["simulate", "simple_pendulum", "--set", "g=diff(t, t)"], "--set"),
        (["simulate", "simple_pendulum", "--initial", "theta=sqrt(-1)"], "--initial"),
        (["linearize", "simple_pendulum", "--about", "theta=pi/"], "--about"),
        (["linearize", "simple_pendulum", "--about", "theta=nan"], "--about"),
        (["linearize", "simple_pendulum", "--about", "theta=1e400**2"], "--about"),
        (["equilibria", "simple_pendulum", "--range", "theta=-1..x"], "--range"),
        (["equilibria", "simple_pendulum", "--range", "theta=1..-1"], "--range"),
    ],
)
def test_expression_options_say_what_is_wrong(args: list[str], option: str) -> None:
    """Never an empty message: `option:1:col: error: <text>`, then usually the value with a caret."""
    code, output = invoke(*args)
    assert code == 2, output
    first = output.splitlines()[0]
    assert option in first and re.search(r"error: \S", first), output
    assert "error: \n" not in output and not first.rstrip().endswith("error:")


def test_until_with_a_derivative_explains_itself() -> None:
    code, output = invoke("simulate", "simple_pendulum", "--until", "diff(theta, t)")
    assert code == 2 and "--until:1:1: error: time derivatives are not allowed in a stop condition" in output and "\n    ^" in output


# --- file text on the terminal --------------------------------------------------------------------


def test_printable_escapes_what_steers_a_terminal() -> None:
    assert printable("a\x1b[2Jb\rc\bd\x07\x85\x9b\u202e\u2066\udcff\x7f") == "a\\x1b[2Jb\\rc\\x08d\\x07\\x85\\x9b\\u202e\\u2066\\udcff\\x7f"
    assert printable("line\n\tindented") == "line\n\tindented" and printable("line\n\t", keep="") == "line\\n\\t"
    assert printable("ordinary text: é, ü, θ, 中, ✓") == "ordinary text: é, ü, θ, 中, ✓"
    assert printable("pa\u200bssed\ufeff\U000e0041") == "pa\\u200bssed\\ufeff\\U000e0041"  # zero-width and tag characters
    rendered = Diagnostic(Span("x\x1b.yaml", 1, 8, 'title: "\x1b[2J"\t# c'), "bad \x1b[31m", "no \u202e").render()
    assert not UNPRINTABLE.search(rendered) and "x\\x1b.yaml:1:8" in rendered and "\\u202e" in rendered
    source, caret = rendered.splitlines()[1:3]
    assert source.index('"') == caret.index("^")  # the caret stays under its column


@pytest.mark.parametrize("text", ["\\[bold]x", "a\\", "[bold]x[/bold]", "[/]", "[/x]", "[link=http://x]y[/link]", ":smile: :red_heart:", "[#ff0000]z", "[@click]q", "x\\\\[/x]"])
def test_inert_text_prints_as_itself_inside_markup(text: str) -> None:
    import io

    from lagrange_cli.cli.boundary import console, inert

    out = console(width=200)
    out.file = io.StringIO()
    out.print(f"[bold]{inert(text)}[/bold]: tail")
    assert out.file.getvalue().rstrip("\n") == f"{text}: tail"


def test_hostile_title_is_inert_in_every_report(tmp_path: Path) -> None:
    """A title with escape sequences, a carriage return, a bidi override, rich markup and an emoji
    code: printed as visible text by every command that shows it."""
    path = tmp_path / "spring.yaml"
    path.write_text(f"title: {HOSTILE_YAML}\ncoordinates: [x]\nparameters:\n  k: {{value: 1.0}}\nkinetic: x_dot**2/2\npotential: k*x**2/2\ninitial: {{x: 1.0}}\n")
    for args in (["simulate", str(path), "--t-end", "0.01", "--backend", "python"], ["info", str(path)], ["equilibria", str(path)], ["linearize", str(path)], ["derive", str(path), "--latex"]):
        code, output = invoke(*args)
        assert code == 0, output
        assert not UNPRINTABLE.search(output), (args, output)
    code, output = invoke("simulate", str(path), "--t-end", "0.01", "--backend", "python")
    assert "\\x1b[2J\\x1b]0;pwned\\x07\\rpassed\\x08 [bold]x[/bold] [/x] \\u202e :smile: \\x9b31m" in output


def test_hostile_file_names_are_inert_in_check(tmp_path: Path) -> None:
    """A file named with markup and escape sequences, with a wrong answer and one that is bad input."""
    wrong = tmp_path / "[bold]wrong[link=x]\x1b[2J.yaml"
    wrong.write_text(PENDULUM.read_text().replace("theta_ddot + g/l*sin(theta) = 0", "theta_ddot + g*sin(theta) = 0"))
    bad = tmp_path / "[red]bad\u202e\r.yaml"
    bad.write_text("coordinates: [x]\nkinetic: x_dot**2/2 +\n")
    code, output = invoke("check", str(tmp_path))
    assert code == 2, output
    assert not UNPRINTABLE.search(output), output
    assert "[bold]wrong[link=x]\\x1b[2J.yaml" in output and "[red]bad\\u202e\\r.yaml" in output


def test_hostile_text_inside_a_file_is_inert_in_error_messages(tmp_path: Path) -> None:
    """A raw bidi override and a YAML-escaped ESC in the source line an error points at."""
    path = tmp_path / "bad.yaml"
    path.write_text('coordinates: [x]\nkinetic: "x_dot**2 \u202e\\e[2J" +\n', encoding="utf-8")
    code, output = invoke("derive", str(path))
    assert code == 2 and not UNPRINTABLE.search(output) and "\\u202e" in output


def test_every_error_is_labelled(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """A library message without a place gets `error: ` in front; one with a place keeps its own."""
    from lagrange_cli.errors import LagrangeError, fail

    for error, first in ((LagrangeError("unknown method 'x'"), "error: unknown method 'x'"), (fail(Span("f.yaml", 1, 1, "x"), "bad"), "f.yaml:1:1: error: bad")):
        with pytest.raises(typer.Exit):
            cli.fail_with(error)
        assert capsys.readouterr().err.splitlines()[0] == first


def test_fail_with_escapes_any_library_message(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    from lagrange_cli.errors import LagrangeError

    with pytest.raises(typer.Exit):
        cli.fail_with(LagrangeError("'\x1b[2Jname[/x]' is wrong\nsecond line"))
    err = capsys.readouterr().err
    assert "\\x1b[2Jname[/x]" in err and "\nsecond line" in err and "\x1b" not in err


# --- the safety net ------------------------------------------------------------------------------


def _raise(error: BaseException) -> object:
    def broken(*args: object, **kwargs: object) -> object:
        raise error

    return broken


@pytest.mark.parametrize(
    "error", [RuntimeError("boom \x1b[2J [bold]x[/x]"), RecursionError("maximum recursion depth exceeded"), MemoryError(), ZeroDivisionError("division by zero")], ids=lambda e: type(e).__name__
)
def test_a_bug_is_one_line_and_exit_2(monkeypatch: pytest.MonkeyPatch, error: BaseException) -> None:
    from lagrange_cli import derive

    monkeypatch.delenv("LAGRANGE_DEBUG", raising=False)
    monkeypatch.setattr(derive, "derive", _raise(error))
    for args in (["derive", "simple_pendulum"], ["info", "simple_pendulum"], ["simulate", "simple_pendulum"], ["stress", "simple_pendulum"]):
        result = runner.invoke(app, args)
        assert result.exit_code == 2 and isinstance(result.exception, SystemExit), (args, result.output)
        lines = [line for line in result.output.splitlines() if line.strip()]
        described = f"{type(error).__name__}: {error}" if str(error) else type(error).__name__
        assert lines == [f"error: internal error while processing simple_pendulum: {printable(described, keep='')} (please report this)"], result.output
        assert "Traceback" not in result.output and "\x1b" not in result.output


def test_a_bug_in_check_is_reported_for_its_file(monkeypatch: pytest.MonkeyPatch) -> None:
    from lagrange_cli import check

    monkeypatch.setattr(check, "check", _raise(RuntimeError("boom")))
    result = runner.invoke(app, ["check", str(PENDULUM), "--json"])
    assert result.exit_code == 2 and "internal error while processing systems/simple_pendulum.yaml: RuntimeError: boom (please report this)" in result.output


def test_lagrange_debug_lets_the_traceback_through(monkeypatch: pytest.MonkeyPatch) -> None:
    from lagrange_cli import derive

    monkeypatch.setenv("LAGRANGE_DEBUG", "1")
    monkeypatch.setattr(derive, "derive", _raise(RuntimeError("boom")))
    result = runner.invoke(app, ["derive", "simple_pendulum"])
    assert isinstance(result.exception, RuntimeError)


def test_main_catches_what_escapes_the_commands(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.delenv("LAGRANGE_DEBUG", raising=False)
    monkeypatch.setattr(cli, "app", _raise(KeyError("x")))
    with pytest.raises(SystemExit) as exit_:
        cli.main()
    assert exit_.value.code == 2 and "internal error while processing" in capsys.readouterr().err


def test_every_output_option_refuses_the_input_file(tmp_path: Path) -> None:
    """Generated from the app: each Path option of each command that reads a system file."""
    source = tmp_path / "pendulum.yaml"
    source.write_bytes(PENDULUM.read_bytes())
    options = output_options()
    assert len(options) >= 8
    for command, option in options:
        code, output = invoke(command, str(source), option, str(source))
        assert code == 2 and "is the input file" in output, (command, option, output)
    assert source.read_bytes() == PENDULUM.read_bytes()
