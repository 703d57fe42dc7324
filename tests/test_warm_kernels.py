"""Kernels compiled ahead in a process of their own (`compile.warm_kernels`): it writes numba's cache, `kernel_entry`
waits for it instead of compiling a kernel twice, nothing starts for kernels already cached or with
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
    monkeypatch.setattr(compile, "_QUEUED", {})


def started() -> list[object]:
    return list(compile._STARTED)


def warming() -> dict[tuple[str, str], object]:
    return dict(compile._WARMING)


def queued() -> dict[tuple[str, str], tuple[str, ...]]:
    return dict(compile._QUEUED)


@pytest.mark.usefixtures("fresh")
def test_a_kernel_compiled_ahead_is_waited_for_and_found_in_the_cache_and_not_started_twice() -> None:
    assert not compile.kernel_cached("no_jacobian")
    compile.warm_kernels(["no_jacobian", "no_jacobian"])
    folder = str(compile.cache_dir())
    process = compile._WARMING[(folder, "no_jacobian")]
    assert started() == [process]
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
    assert warming() == {(folder, "radau_start"): process, (folder, "radau_run"): process}
    compile._stop_warming()
    assert process.poll() is not None and warming() == {}


@pytest.mark.usefixtures("fresh")
def test_a_study_warms_radau_for_the_system_and_the_symplectic_method_apart(monkeypatch: pytest.MonkeyPatch) -> None:
    """A conservative system without constraints: radau_start and radau_run in one process, gauss_run in another; a
    study without Radau or the symplectic method starts nothing."""
    groups: list[list[str]] = []
    monkeypatch.setattr(compile, "warm_kernels", lambda names, later=False: groups.append([*names, *(["(later)"] if later else [])]))
    from .conftest import ROOT

    kepler = model_from(ROOT / "tests" / "numeric_audit2" / "kepler_e09.yaml")
    runs.warm_study(kepler, runs.default_candidates(kepler))
    assert groups == [["radau_start", "radau_run"], ["gauss_run", "(later)"]]
    groups.clear()
    pendulum = model_from(ROOT / "tests" / "numeric_audit3" / "pendulum_multiplier_large_swing.yaml")
    runs.warm_study(pendulum, runs.default_candidates(pendulum))
    assert groups == [["radau_start", "radau_projected"]]  # kept constraints: projected, and no symplectic method
    groups.clear()
    runs.warm_study(kepler, (Candidate("DOP853", "compiled"), Candidate("RK45")))
    assert groups == []


@pytest.mark.usefixtures("fresh")
def test_a_group_needed_later_waits_for_the_running_one_or_for_this_process_to_need_it(monkeypatch: pytest.MonkeyPatch) -> None:
    """`warm_kernels(later=True)` (the symplectic method's loop behind Radau's) is queued while a process compiling ahead
    runs, so that two compiling processes and this one do not share a two-core machine; it starts once none runs, or
    when this process needs one of its kernels (and would otherwise wait with its core idle)."""
    import subprocess
    import sys

    blocker = subprocess.Popen([sys.executable, "-c", "import sys; sys.stdin.read()"], stdin=subprocess.PIPE)  # a process compiling ahead, until told
    compile._STARTED.append(blocker)
    folder = str(compile.cache_dir())
    try:
        compile.warm_kernels(["no_jacobian"], later=True)
        assert started() == [blocker]
        assert queued() == {(folder, "no_jacobian"): ("no_jacobian",)}
        compile.warm_kernels(["no_jacobian"], later=True)  # queued already: nothing more
        compile._release(waiting=False)  # the blocker still runs
        assert started() == [blocker] and warming() == {}
        entry = compile.kernel_entry(compile.kernels_module(), "no_jacobian")  # needed now: started, and waited for
        assert entry is not None and queued() == {}
        (process,) = started()[1:]
        process.wait()
        assert process.returncode == 0 and compile.kernel_cached("no_jacobian")
        monkeypatch.setattr(compile, "kernel_cached", lambda name: False)  # as if radau_start were not cached yet
        compile.warm_kernels(["radau_start"], later=True)
        assert (folder, "radau_start") in queued()
    finally:
        assert blocker.stdin is not None
        blocker.stdin.close()
        blocker.wait()
    compile._release(waiting=False)  # none runs now: the queued group starts
    assert queued() == {} and (folder, "radau_start") in warming()
    compile._stop_warming()
    assert all(p.poll() is not None for p in started())
