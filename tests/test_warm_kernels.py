"""Kernels compiled ahead in a process of their own (`compile.warm_kernels`): it writes numba's cache, `kernel_entry`
waits for a kernel it has begun instead of compiling it twice (and compiles one it has not reached), nothing starts for kernels already cached or with
LAGRANGE_NO_WARM set, and no process outlives the command (`_stop_warming`). Nothing here reads a clock: the
waits end on the cache file or the process's end."""

from __future__ import annotations

import pytest

from lagrange_cli.numeric import compile, runs
from lagrange_cli.numeric.runs import Candidate

from .helpers import model_from

pytestmark = pytest.mark.skipif(not compile.numba_available(), reason="kernels are compiled by numba")


@pytest.fixture()
def fresh(tmp_path: object, monkeypatch: pytest.MonkeyPatch) -> None:
    """An empty cache of this test's own, and no process started ahead by another test."""
    monkeypatch.setenv("LAGRANGE_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv("LAGRANGE_NO_WARM", raising=False)
    monkeypatch.setattr(compile, "_WARMING", {})
    monkeypatch.setattr(compile, "_STARTED", [])


def started() -> list[object]:
    return list(compile._STARTED)


def warming() -> dict[tuple[str, str], object]:
    return dict(compile._WARMING)


@pytest.mark.usefixtures("fresh")
def test_a_kernel_compiled_ahead_is_waited_for_and_found_in_the_cache_and_not_started_twice() -> None:
    assert not compile.kernel_cached("no_jacobian")
    compile.warm_kernels(["no_jacobian", "no_jacobian"])
    folder = str(compile.cache_dir())
    process, before = compile._WARMING[(folder, "no_jacobian")]
    assert before == () and started() == [process]
    compile.warm_kernels(["no_jacobian"])  # being compiled ahead already: nothing more started
    assert started() == [process]
    entry = compile.kernel_entry(compile.kernels_module(), "no_jacobian")
    assert entry is not None and (folder, "no_jacobian") not in compile._WARMING
    process.wait()
    assert process.returncode == 0 and compile.kernel_cached("no_jacobian")
    compile.warm_kernels(["no_jacobian"])  # in the cache: nothing started
    assert started() == [process]


@pytest.mark.usefixtures("fresh")
def test_nothing_is_started_where_it_is_turned_off_and_a_started_process_is_stopped_at_exit(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("LAGRANGE_NO_WARM", "1")
    compile.warm_kernels(["radau_start", "radau_run"])
    assert started() == []
    monkeypatch.delenv("LAGRANGE_NO_WARM")
    compile.warm_kernels(["radau_start", "radau_run"])
    (process,) = compile._STARTED
    folder = str(compile.cache_dir())
    assert warming() == {(folder, "radau_start"): (process, ()), (folder, "radau_run"): (process, ("radau_start",))}
    compile._stop_warming()
    assert process.poll() is not None and warming() == {}


@pytest.mark.usefixtures("fresh")
def test_a_study_warms_radau_for_the_system_then_the_symplectic_method(monkeypatch: pytest.MonkeyPatch) -> None:
    """A conservative system without constraints: radau_start, radau_run and then gauss_run, in the order a study
    needs them, in one process; a study without Radau or the symplectic method starts nothing."""
    groups: list[list[str]] = []
    monkeypatch.setattr(compile, "warm_kernels", lambda names: groups.append(list(names)))
    from .conftest import ROOT

    kepler = model_from(ROOT / "tests" / "numeric_audit2" / "kepler_e09.yaml")
    runs.warm_study(kepler, runs.default_candidates(kepler))
    assert groups == [["radau_start", "radau_run", "gauss_run"]]
    groups.clear()
    pendulum = model_from(ROOT / "tests" / "numeric_audit3" / "pendulum_multiplier_large_swing.yaml")
    runs.warm_study(pendulum, runs.default_candidates(pendulum))
    assert groups == [["radau_start", "radau_projected"]]  # kept constraints: projected, and no symplectic method
    groups.clear()
    runs.warm_study(kepler, (Candidate("DOP853", "compiled"), Candidate("RK45")))
    assert groups == []


class _Process:
    """A stand-in for the process compiling ahead: running until `ends_after` looks at it (never, with None)."""

    def __init__(self, ends_after: int | None) -> None:
        self.looks, self.ends_after = 0, ends_after

    def poll(self) -> int | None:
        self.looks += 1
        return 0 if self.ends_after is not None and self.looks >= self.ends_after else None


@pytest.mark.usefixtures("fresh")
def test_a_kernel_the_process_has_not_reached_is_compiled_here_and_one_it_has_begun_is_waited_for(monkeypatch: pytest.MonkeyPatch) -> None:
    """The process compiles its kernels in order: while radau_run (not in the cache) is before no_jacobian, the
    process has not begun no_jacobian, and waiting would wait for radau_run too: compiled here at once (the process
    looked at once). With nothing before it, the process is waited for until it ends (looked at three times)."""
    folder = str(compile.cache_dir())
    monkeypatch.setattr(compile, "WARM_POLL", 0.0)
    kernels = compile.kernels_module()
    behind = _Process(None)
    compile._WARMING[(folder, "no_jacobian")] = (behind, ("radau_run",))
    assert compile.kernel_entry(kernels, "no_jacobian") is not None
    assert behind.looks == 1 and (folder, "no_jacobian") not in compile._WARMING
    begun = _Process(3)
    compile._WARMING[(folder, "erk_start")] = (begun, ())
    assert compile.kernel_entry(kernels, "erk_start") is not None
    assert begun.looks == 3
