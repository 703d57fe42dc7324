"""The pre-commit hook in the real `pre-commit`, in a throwaway course repository.

The hook repository is a git copy of this working tree (committed there, so the test sees
uncommitted work too); the course repository names it in its `.pre-commit-config.yaml` and
runs `pre-commit install`, so `git commit` runs the hook as it does for users. pre-commit
installs the hook repository with pip into an environment of its own (a plain install: no
extras). That environment is built once for the module, in a fresh PRE_COMMIT_HOME, so
nothing cached hides a missing dependency. (`pre-commit try-repo` runs the same hook
definition but builds its environment anew in a temporary store on every call.)
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
import yaml

from .conftest import ROOT
from .limits import DEADLOCK

pytestmark = pytest.mark.slow

PRE_COMMIT = Path(sys.executable).with_name("pre-commit")
GOOD = (ROOT / "systems" / "simple_pendulum.yaml").read_text()
WRONG = GOOD.replace("theta_ddot + g/l*sin(theta) = 0", "theta_ddot + l/g*sin(theta) = 0")
HOOK = yaml.safe_load((ROOT / ".pre-commit-hooks.yaml").read_text())[0]


def git(cwd: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["git", *args], cwd=cwd, capture_output=True, text=True, timeout=DEADLOCK, env=ENV)


ENV = {
    **os.environ,
    "GIT_AUTHOR_NAME": "t",
    "GIT_AUTHOR_EMAIL": "t@example.org",
    "GIT_COMMITTER_NAME": "t",
    "GIT_COMMITTER_EMAIL": "t@example.org",
    "GIT_CONFIG_NOSYSTEM": "1",
    "GIT_CONFIG_GLOBAL": os.devnull,
}


def hook_repository(path: Path) -> str:
    """This working tree (tracked and untracked files, not ignored ones) as a git repository
    with one commit; returns the commit."""
    listed = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=ROOT, capture_output=True, text=True, check=True)
    for name in filter(None, listed.stdout.split("\0")):
        source = ROOT / name
        if source.is_file() and not name.startswith("tests/golden/"):
            (path / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, path / name)
    git(path, "init", "-q")
    git(path, "add", "-A")
    assert git(path, "commit", "-q", "-m", "hook repository").returncode == 0
    return git(path, "rev-parse", "HEAD").stdout.strip()


@pytest.fixture(scope="module")
def course(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Path, dict[str, str]]]:
    """A course repository whose pre-commit hook is lagrange-check from the hook repository."""
    if shutil.which("git") is None or not PRE_COMMIT.exists():
        pytest.fail("needs git and pre-commit (the dev extra)")
    hooks = tmp_path_factory.mktemp("hook-repo")
    rev = hook_repository(hooks)
    repo = tmp_path_factory.mktemp("course")
    env = {**ENV, "PRE_COMMIT_HOME": str(tmp_path_factory.mktemp("pre-commit-home"))}
    config = f"repos:\n  - repo: {hooks}\n    rev: {rev}\n    hooks:\n      - id: lagrange-check\n"
    files = {
        ".pre-commit-config.yaml": config,
        "systems/pendulum.yaml": GOOD,
        ".github/workflows/ci.yml": "on: push\njobs: {}\n",
        "notes.yaml": "week: 3\ntopics: [pendulum]\n",
    }
    for name, text in files.items():
        (repo / name).parent.mkdir(parents=True, exist_ok=True)
        (repo / name).write_text(text)
    git(repo, "init", "-q")
    git(repo, "add", "-A")
    assert git(repo, "commit", "-q", "-m", "start").returncode == 0
    installed = subprocess.run([str(PRE_COMMIT), "install"], cwd=repo, capture_output=True, text=True, timeout=DEADLOCK, env=env)
    assert installed.returncode == 0, installed.stdout + installed.stderr
    yield repo, env


def test_the_hook_selects_system_files_only() -> None:
    pattern = re.compile(HOOK["files"])
    for path in ("systems/pendulum.yaml", "course/week3/systems/top.yml", "homework/cart.lagrange.yaml"):
        assert pattern.search(path), path
    for path in (".pre-commit-config.yaml", ".github/workflows/ci.yml", "notes.yaml", "systems.yaml", "docs/mkdocs.yml"):
        assert not pattern.search(path), path
    assert HOOK["language"] == "python" and HOOK["entry"] == "lagrange check" and HOOK.get("pass_filenames", True)


def test_a_correct_system_file_passes_and_other_yaml_is_left_alone(course: tuple[Path, dict[str, str]]) -> None:
    repo, env = course
    result = subprocess.run([str(PRE_COMMIT), "run", "--all-files"], cwd=repo, capture_output=True, text=True, timeout=DEADLOCK, env=env)
    assert result.returncode == 0, result.stdout + result.stderr
    assert re.search(r"lagrange check\.+Passed", result.stdout), result.stdout
    assert "unknown key" not in result.stdout and "Traceback" not in result.stdout


def test_a_wrong_answer_blocks_the_commit(course: tuple[Path, dict[str, str]]) -> None:
    repo, env = course
    before = git(repo, "rev-parse", "HEAD").stdout
    (repo / "systems" / "pendulum.yaml").write_text(WRONG)
    git(repo, "add", "systems/pendulum.yaml")
    commit = subprocess.run(["git", "commit", "-m", "a wrong answer"], cwd=repo, capture_output=True, text=True, timeout=DEADLOCK, env=env)
    assert commit.returncode != 0, commit.stdout + commit.stderr
    assert re.search(r"lagrange check\.+Failed", commit.stdout + commit.stderr)
    assert "FAIL" in commit.stdout + commit.stderr and "Traceback" not in commit.stdout + commit.stderr
    assert git(repo, "rev-parse", "HEAD").stdout == before
    (repo / "systems" / "pendulum.yaml").write_text(GOOD.replace("Simple pendulum", "Simple pendulum, corrected"))
    git(repo, "add", "systems/pendulum.yaml")
    fixed = subprocess.run(["git", "commit", "-m", "the right answer"], cwd=repo, capture_output=True, text=True, timeout=DEADLOCK, env=env)
    assert fixed.returncode == 0, fixed.stdout + fixed.stderr
