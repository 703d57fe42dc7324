"""Files in and out (issue 11, class 8): only regular input files are read, and a bounded size of
them; names no file can have are messages; outputs never replace a device, a FIFO or an input,
keep the old file's mode or take the umask's, and `-` is standard output."""

from __future__ import annotations

import os
import stat
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from typer.testing import CliRunner

from lagrange_cli import spec
from lagrange_cli.cli import app
from lagrange_cli.errors import LagrangeError, SpecError
from lagrange_cli.files import atomic_write, read_limited, write_text

from .conftest import ROOT
from .limits import DEADLOCK

runner = CliRunner()
PENDULUM = ROOT / "systems" / "simple_pendulum.yaml"


def run(*args: str) -> tuple[int, str]:
    result = runner.invoke(app, list(args))
    assert "Traceback" not in result.output and "internal error" not in result.output, result.output
    assert result.exception is None or isinstance(result.exception, SystemExit), repr(result.exception)
    return result.exit_code, result.output


def lagrange(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    """The real command in a subprocess; the timeout only keeps a regression (a hang) from stalling the suite."""
    environment = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", "lagrange_cli", *args], cwd=cwd, capture_output=True, text=True, timeout=DEADLOCK, env=environment)


@pytest.fixture
def pendulum(tmp_path: Path) -> Path:
    path = tmp_path / "pendulum.yaml"
    path.write_bytes(PENDULUM.read_bytes())
    path.chmod(0o644)
    return path


@pytest.fixture
def umask() -> Iterator[None]:
    old = os.umask(0o022)
    yield
    os.umask(old)


# --- inputs --------------------------------------------------------------------------------------


def test_a_fifo_as_input_is_refused_without_waiting(tmp_path: Path) -> None:
    """Opening a FIFO for reading blocks until a writer comes; the file is opened without blocking
    and refused for its type."""
    os.mkfifo(tmp_path / "pipe.yaml")
    done = lagrange("derive", "pipe.yaml", cwd=tmp_path)
    assert done.returncode == 2 and "cannot read 'pipe.yaml': it is a FIFO" in done.stderr and "Traceback" not in done.stderr


def test_a_link_to_dev_zero_is_refused(tmp_path: Path) -> None:
    (tmp_path / "zero.yaml").symlink_to("/dev/zero")
    code, output = run("derive", str(tmp_path / "zero.yaml"))
    assert code == 2 and "it is a character device" in output and "zero.yaml" in output


def test_a_directory_as_input_is_refused(tmp_path: Path) -> None:
    code, output = run("derive", str(tmp_path))
    assert code == 2 and "it is a directory" in output


def test_an_unreadable_file_is_a_message(pendulum: Path) -> None:
    if os.geteuid() == 0:
        pendulum.unlink()
        pendulum.symlink_to(pendulum.parent / "loop.yaml")
        (pendulum.parent / "loop.yaml").symlink_to(pendulum)  # root reads any file; a link loop is unreadable for everyone
    else:
        pendulum.chmod(0)
    code, output = run("derive", str(pendulum))
    assert code == 2 and f"cannot read '{pendulum}'" in output


def test_only_a_bounded_prefix_of_a_huge_file_is_read(tmp_path: Path) -> None:
    """A sparse 4 GB file: refused for its size after reading just over the limit."""
    path = tmp_path / "huge.yaml"
    with path.open("wb") as stream:
        stream.truncate(4 << 30)
    assert len(read_limited(path, 1000)) == 1001
    code, output = run("derive", str(path))
    assert code == 2 and f"file is over {spec.MAX_FILE_BYTES} bytes" in output


@pytest.mark.parametrize(
    ("name", "problem"),
    [("a" * 300 + ".yaml", "too long"), ("d/" * 2100 + "x.yaml", "too long"), ("x" * 5000, "too long"), ("sys\0tem.yaml", "NUL byte"), ("caf\udce9.yaml", "not valid UTF-8"), ("", "empty")],
    ids=["300-char name", "long path", "5000-char name", "NUL", "not UTF-8", "empty"],
)
def test_impossible_names_are_messages(name: str, problem: str) -> None:
    """The library (resolve and load) and the command line both say what is wrong with the name."""
    for call in (spec.resolve, spec.load):
        with pytest.raises(SpecError, match=problem):
            call(name)
    for command in (["derive", name], ["check", name], ["info", name]):
        code, output = run(*command)
        assert code == 2 and problem in output and "\0" not in output and "\udce9" not in output


def test_a_name_with_control_characters_is_shown_escaped(tmp_path: Path) -> None:
    code, output = run("derive", str(tmp_path / "\x1b[2J\rok.yaml"))
    assert code == 2 and "\x1b" not in output and "\r" not in output and "\\x1b[2J\\rok.yaml" in output


# --- outputs -------------------------------------------------------------------------------------


def test_output_onto_the_input_is_refused_before_any_work(pendulum: Path) -> None:
    before = pendulum.read_bytes()
    (pendulum.parent / "link.yaml").symlink_to(pendulum)
    spellings = [str(pendulum), f"{pendulum.parent}/./{pendulum.name}", str(pendulum.parent / "link.yaml"), f"{pendulum.parent}/../{pendulum.parent.name}/{pendulum.name}"]
    for spelling in spellings:
        for command in (["derive", str(pendulum), "-o", spelling], ["info", str(pendulum), "--json", "-o", spelling], ["check", str(pendulum), "--junit", spelling]):
            code, output = run(*command)
            assert code == 2 and "is the input file" in output, (command, output)
    code, output = run("derive", "simple_pendulum", "-o", str(PENDULUM))  # a bundled name resolves to the file it reads
    assert code == 2 and "is the input file" in output
    assert pendulum.read_bytes() == before and sorted(p.name for p in pendulum.parent.iterdir()) == ["link.yaml", "pendulum.yaml"]


def test_two_outputs_of_one_command_may_not_share_a_file(tmp_path: Path) -> None:
    target = str(tmp_path / "same.csv")
    code, output = run("accuracy", "simple_pendulum", "--csv", target, "--json", target)
    assert code == 2 and "--csv and --json both write" in output
    code, output = run("simulate", "simple_pendulum", "-o", target, "--plot", f"{tmp_path}/./same.csv")
    assert code == 2 and "-o and --plot both write" in output
    assert list(tmp_path.iterdir()) == []


def test_dash_is_standard_output(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    for command, marker in (
        (["derive", "simple_pendulum", "-o", "-"], "theta_ddot"),
        (["info", "simple_pendulum", "-o", "-"], "degrees of freedom"),
        (["check", "simple_pendulum", "--junit", "-"], "<testsuite"),
    ):
        code, output = run(*command)
        assert code == 0 and marker in output, output
    assert list(tmp_path.iterdir()) == []


def test_dev_null_is_written_in_place_and_stays_a_device() -> None:
    code, output = run("derive", "simple_pendulum", "-o", "/dev/null")
    assert code == 0 and output == ""
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)


def test_dev_stdout_writes_through_the_open_descriptor(tmp_path: Path) -> None:
    """`-o /dev/stdout` with stdout redirected to a file: the output lands where the shell's
    descriptor points (after what was written before), and the file is not replaced."""
    target = tmp_path / "log.txt"
    environment = {**os.environ, "PYTHONPATH": str(ROOT)}
    with target.open("wb") as stream:
        stream.write(b"first\n")
        stream.flush()
        inode = os.fstat(stream.fileno()).st_ino
        done = subprocess.run([sys.executable, "-m", "lagrange_cli", "derive", "simple_pendulum", "-o", "/dev/stdout"], stdout=stream, stderr=subprocess.PIPE, timeout=DEADLOCK, env=environment)
        stream.write(b"last\n")
    assert done.returncode == 0, done.stderr
    lines = target.read_text().splitlines()
    assert lines[0] == "first" and "theta_ddot" in lines[1] and lines[-1] == "last" and target.stat().st_ino == inode


def test_a_fifo_without_a_reader_is_refused_and_stays_a_fifo(tmp_path: Path) -> None:
    fifo = tmp_path / "out.txt"
    os.mkfifo(fifo)
    done = lagrange("derive", "simple_pendulum", "-o", "out.txt", cwd=tmp_path)
    assert done.returncode == 2 and "no process is reading" in done.stderr
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode) and sorted(p.name for p in tmp_path.iterdir()) == ["out.txt"]


def test_a_fifo_with_a_reader_receives_the_output(tmp_path: Path) -> None:
    fifo = tmp_path / "out.txt"
    os.mkfifo(fifo)
    reader = os.open(fifo, os.O_RDONLY | os.O_NONBLOCK)
    try:
        code, _ = run("derive", "simple_pendulum", "-o", str(fifo))
        received = os.read(reader, 1 << 16)
    finally:
        os.close(reader)
    assert code == 0 and b"theta_ddot" in received
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)


def test_other_special_outputs_are_refused(tmp_path: Path) -> None:
    code, output = run("derive", "simple_pendulum", "-o", str(tmp_path))
    assert code == 2 and "it is a directory" in output
    code, output = run("derive", "simple_pendulum", "-o", str(tmp_path / ("o" * 300)))
    assert code == 2 and "too long" in output
    code, output = run("derive", "simple_pendulum", "-o", str(tmp_path / "not-a-dir" / "x"))
    assert code == 2
    for name, problem in ((f"{tmp_path}/a\0b", "nul"), (f"{tmp_path}/caf\udce9", "not valid utf-8")):  # typer itself refuses a NUL in a Path option
        for args in (["derive", "simple_pendulum", "-o", name], ["check", "simple_pendulum", "--junit", name], ["stress", "simple_pendulum", "--json", name]):
            code, output = run(*args)
            assert code == 2 and problem in output.lower() and "\0" not in output
    code, output = run("derive", "simple_pendulum", "-o", "/dev/full")
    assert code == 2 and "cannot write /dev/full: No space left on device" in output
    assert list(tmp_path.iterdir()) == []


@pytest.mark.usefixtures("umask")
@pytest.mark.parametrize("mask", [0o022, 0o077])
def test_a_new_output_takes_its_mode_from_the_umask(tmp_path: Path, mask: int) -> None:
    os.umask(mask)
    code, _ = run("derive", "simple_pendulum", "-o", str(tmp_path / "eom.txt"))
    assert code == 0 and stat.S_IMODE((tmp_path / "eom.txt").stat().st_mode) == 0o666 & ~mask


@pytest.mark.usefixtures("umask")
@pytest.mark.parametrize("mode", [0o644, 0o600, 0o664])
def test_a_replaced_output_keeps_its_mode(tmp_path: Path, mode: int) -> None:
    os.umask(0o077)
    target = tmp_path / "eom.txt"
    target.write_text("old\n")
    target.chmod(mode)
    code, _ = run("derive", "simple_pendulum", "-o", str(target))
    assert code == 0 and "theta_ddot" in target.read_text()
    assert stat.S_IMODE(target.stat().st_mode) == mode


def test_a_private_file_is_0600(tmp_path: Path) -> None:
    target = tmp_path / "cached.py"
    target.write_text("old\n")
    target.chmod(0o644)
    write_text(target, "new\n", private=True)
    assert stat.S_IMODE(target.stat().st_mode) == 0o600


def test_set_id_bits_are_not_copied(tmp_path: Path) -> None:
    target = tmp_path / "tool"
    target.write_text("old\n")
    target.chmod(0o4755)
    write_text(target, "new\n")
    assert stat.S_IMODE(target.stat().st_mode) == 0o755


def test_a_link_to_an_output_stays_a_link(tmp_path: Path) -> None:
    real = tmp_path / "real.txt"
    real.write_text("old\n")
    (tmp_path / "link.txt").symlink_to(real)
    write_text(tmp_path / "link.txt", "new\n")
    assert (tmp_path / "link.txt").is_symlink() and real.read_text() == "new\n"


def test_a_failed_write_leaves_the_old_file(tmp_path: Path) -> None:
    target = tmp_path / "kept.txt"
    target.write_text("old\n")

    def broken(stream: object) -> None:
        raise OSError(28, "No space left on device")

    with pytest.raises(LagrangeError, match="No space left"):
        atomic_write(target, broken)
    assert target.read_text() == "old\n" and [p.name for p in tmp_path.iterdir()] == ["kept.txt"]


# --- check: what it reads ------------------------------------------------------------------------


def test_check_refuses_a_glob_or_directory_that_matches_nothing(tmp_path: Path) -> None:
    """A mistyped glob must not pass CI: exit 2, naming the argument."""
    (tmp_path / "empty").mkdir()
    for args in ([str(tmp_path / "nothing*.yaml")], [str(tmp_path / "empty")], [str(PENDULUM), str(tmp_path / "typo*.yaml")]):
        code, output = run("check", *args)
        assert code == 2 and "no system files matched" in output, output
    result = runner.invoke(app, ["check"])
    assert result.exit_code == 2
    code, output = run("check", str(ROOT / "systems" / "simple_pendulum*.yaml"))
    assert code == 0 and "1 passed" in output
